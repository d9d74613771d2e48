"""Defaults shared by several modules: each one is written here once and referenced elsewhere.

A default that only one dataclass field uses stays beside that field; the ones below are
repeated by the commands' options, the daemon's configuration and the simulations, so they
live here and every other place names them.
"""
from __future__ import annotations

__all__ = ["CONTROL_RATE_HZ", "MAX_PREDICTION_S", "STALE_TIMEOUT_S"]

CONTROL_RATE_HZ = 500.0
"""The vehicle's telemetry (control) rate the daemon regulates at, Hz: ``--control-rate-hz``
of ``fly`` and ``serve``, the bundled emulator's rate, the simulations' controller rate."""

MAX_PREDICTION_S = 0.1
"""Cap on the delay prediction's horizon, s (the controller file's ``max_prediction_s``, and
the daemon's horizon when no controller file is given); past it a gap is not flown on the
prediction."""

STALE_TIMEOUT_S = 0.5
"""No complete sample for this long while armed: the link is lost, the stream stops for good
and the vehicle's failsafe takes over, s (``--stale-timeout-s``, docs/safety.md)."""
