"""Why the simulation stopped, and the process exit code for each reason."""
from __future__ import annotations

import enum

__all__ = ["ExitCode", "SimStop"]


class ExitCode(enum.IntEnum):
    """Process exit status of ``firmware-sim`` (documented in docs/firmware_sim.md)."""

    OK = 0              # --duration-s reached, SIGINT or SIGTERM
    INTERNAL = 1        # a bug: unexpected exception
    USAGE = 2           # bad command line or YAML
    CRASH = 3           # touched the ground too fast or too tilted
    NON_FINITE = 4      # NaN or inf in the state
    LIMIT = 5           # speed or body rate beyond the emulator's limits


class SimStop(Exception):
    """The vehicle's flight ended (crash, non-finite state, limit exceeded)."""

    def __init__(self, code: ExitCode, reason: str):
        super().__init__(reason)
        self.code = code
        self.reason = reason
