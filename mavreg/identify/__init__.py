"""Calibration of a vehicle from one flight (``mavreg identify``): :mod:`.fit` is the math
(arrays in, numbers out), :mod:`.flightlog` reads a flight's ``.tlog``."""
