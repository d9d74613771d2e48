"""Linux /proc helpers for tests that check which processes are alive."""
from __future__ import annotations

import os
import time


def start_time(pid: int) -> int | None:
    """The process's start time (clock ticks since boot), or None when it does not exist.

    A zombie counts as gone (it has exited; only its parent has not reaped it yet).
    """
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
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
