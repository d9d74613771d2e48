"""Child processes that die with the daemon, however the daemon ends (SIGKILL included).

The daemon starts two kinds of children: the planner worker (:mod:`.planner_pool`) and,
for ``mavreg fly``, the bundled emulator. Neither may outlive it. Two mechanisms, both
armed in the child itself:

- **Linux**: ``prctl(PR_SET_PDEATHSIG, SIGKILL)`` (through ``ctypes``): the kernel kills
  the child when its parent dies. The setting survives ``execve`` and acts even on a
  child that is stopped or busy. It fires when the *thread* that started the child ends,
  so children must be started from a thread that lives as long as the daemon (the
  event-loop thread does).
- **Anywhere**: :func:`watch_parent` starts a daemon thread that polls ``os.getppid()``
  and ends the process when the parent changes (the child was re-parented).

Both check the race where the parent died before they were armed: the child compares
``os.getppid()`` with the parent pid it was given and exits at once if they differ.

Run as a program, this module is an exec wrapper for children that are not Python
functions of ours (the emulator)::

    python -m mavreg.daemon.jobs.lifeline PARENT_PID PROGRAM [ARG ...]

arms the parent-death signal, then ``execvp``\\ s PROGRAM (same pid, so signals sent to
the child reach PROGRAM directly).
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
import time

__all__ = ["set_parent_death_signal", "watch_parent", "die_with_parent", "wrap_command"]

PR_SET_PDEATHSIG = 1
"""From <linux/prctl.h>."""

WATCH_PERIOD_S = 0.25
"""How often the portable watcher looks at ``os.getppid()``."""


def set_parent_death_signal(sig: int = signal.SIGKILL) -> bool:
    """Ask the Linux kernel to send ``sig`` to this process when its parent dies.

    Returns
    -------
    bool
        True when armed; False on other systems or when ``prctl`` is unavailable.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _end_now() -> None:
    os._exit(1)


def watch_parent(parent_pid: int, period_s: float = WATCH_PERIOD_S) -> threading.Thread:
    """Start a daemon thread that ends this process once ``os.getppid()`` is not ``parent_pid``.

    Parameters
    ----------
    parent_pid : int
        The pid of the process this one must not outlive.
    period_s : float
        Polling period (s).
    """
    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(period_s)
        _end_now()
    thread = threading.Thread(target=watch, name="lifeline", daemon=True)
    thread.start()
    return thread


def die_with_parent(parent_pid: int, watcher: bool = True) -> None:
    """Arm the parent-death signal (Linux) and, optionally, the portable watcher thread.

    Exits at once when the parent is already gone (``os.getppid() != parent_pid``).
    """
    set_parent_death_signal()
    if os.getppid() != parent_pid:
        _end_now()
    if watcher:
        watch_parent(parent_pid)


def wrap_command(cmd: list[str]) -> list[str]:
    """``cmd`` run through this module's exec wrapper, bound to the calling process."""
    return [sys.executable, "-m", __name__, str(os.getpid()), *cmd]


def main(argv: list[str]) -> int:
    if len(argv) < 2 or not argv[0].isdigit():
        print("usage: python -m mavreg.daemon.jobs.lifeline PARENT_PID PROGRAM [ARG ...]", file=sys.stderr)
        return 2
    die_with_parent(int(argv[0]), watcher=False)   # a thread would not survive execvp
    try:
        os.execvp(argv[1], argv[1:])
    except OSError as exc:
        print(f"lifeline: cannot run {argv[1]!r}: {exc}", file=sys.stderr)
        return 127


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
