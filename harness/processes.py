"""A process by its PID, read from Linux's ``/proc``: is it alive, its start time, children and
command line; wait until a set of them is gone; stop one (SIGTERM, then SIGKILL).

For processes a test did not start as a child it can wait on (the ArduCopter SITL that
``start.sh`` leaves behind, a daemon's emulator and planner worker). A process is told from a
later one with its PID by its start time."""
from __future__ import annotations

import os
import signal
import time

__all__ = ["alive", "children", "cmdline", "start_time", "survivors", "terminate"]


def alive(pid: int) -> bool:
    """True while ``pid`` runs (not a zombie), by its ``/proc`` entry."""
    return start_time(pid) is not None


def start_time(pid: int) -> int | None:
    """The process's start time (clock ticks since boot), or None when it does not exist.

    A zombie counts as gone (it has exited; only its parent has not reaped it yet).
    """
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return None if fields[0] in ("Z", "X") else int(fields[19])


def children(pid: int) -> list[int]:
    """Direct children of ``pid`` (every thread's)."""
    out = []
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except FileNotFoundError:
        return []
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/children") as f:
                out += [int(c) for c in f.read().split()]
        except FileNotFoundError:
            pass
    return sorted(set(out))


def cmdline(pid: int) -> str:
    """The process's command line, its arguments joined by spaces ("" when it is gone)."""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return f.read().replace(b"\0", b" ").decode(errors="replace")
    except FileNotFoundError:
        return ""


def survivors(procs: dict[int, int | None], bound_s: float = 10.0) -> list[int]:
    """Poll until none of ``{pid: start_time}`` is alive, for at most ``bound_s``; return those left."""
    deadline = time.monotonic() + bound_s
    while True:
        left = [p for p, t0 in procs.items() if t0 is not None and start_time(p) == t0]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.05)


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
