"""The flight logic, sans-I/O: the supervisor and its parts.

Telemetry samples, messages and the vehicle's time in; commands, phase changes and records
out. Nothing here opens a socket, runs an event loop or reads a clock: the adapters in
:mod:`mavreg.daemon.vehicle` and :mod:`mavreg.daemon.jobs` do, with the clock injected, so
link faults and timing are tested deterministically.
"""
