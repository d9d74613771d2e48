"""A process by its PID: is it alive, and stop it (SIGTERM, then SIGKILL).

For processes a test did not start as a child it can wait on (the ArduCopter SITL that
``start.sh`` leaves behind)."""
from __future__ import annotations

import os
import signal
import time

__all__ = ["alive", "terminate"]


def alive(pid: int) -> bool:
    """True while ``pid`` runs (not a zombie), by its ``/proc`` entry."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except OSError:
        return False


def terminate(pid: int, grace_s: float = 10.0) -> None:
    """SIGTERM ``pid``, SIGKILL it if still alive after ``grace_s``."""
    for sig, wait_s in ((signal.SIGTERM, grace_s), (signal.SIGKILL, 5.0)):
        try:
            os.kill(pid, sig)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            if not alive(pid):
                return
            time.sleep(0.05)
