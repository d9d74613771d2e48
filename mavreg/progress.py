"""What a command is doing while it starts: one line per stage, on stderr.

A first run on a machine compiles the controller's kernels and plans the maneuver, which on
a companion computer takes a minute or more; a user who sees nothing thinks it hung. A
:class:`Progress` says each slow stage as it begins, repeats it while it lasts (every
``every_s``) and says when it is done and how long it took. Its lines have the daemon's
event format (``daemon  12.345 s  ... [start] setup: ...``: :meth:`Progress.line`), so a
flight's output reads as one log.

A stage expected to be quick (a warm cache) is not announced: :meth:`Progress.stage` with
``announce=False`` says it only if it is still running after ``late_s`` (the guess was
wrong: a cache that did not fit, a loaded machine).

The clock and the writer are injected (tests: a fake clock and a list); the repeating line
comes from a daemon thread, which gets the interpreter between the bytecodes of a compile or
a plan. Light on purpose (no numpy, no numba): the command line prints its first line
before it imports the rest.
"""
from __future__ import annotations

import math
import sys
import threading
import time
from typing import Callable

__all__ = ["Progress", "Stage", "cpu_speed_factor", "stderr_line", "REFERENCE_LOOP_S"]

REFERENCE_LOOP_S = 0.030
"""Seconds a 1-million-iteration empty Python loop took (CPython 3.11, ``nice -n 19``, a load
average of 3) on the machine the stage estimates were measured on, the developers' 2-core
machine: :func:`cpu_speed_factor`'s reference."""


def cpu_speed_factor(iterations: int = 100_000, clock_s: Callable[[], float] = time.perf_counter) -> float:
    """How many times slower than the reference machine this one runs Python now (load
    included): the median of three empty loops of ``iterations`` (3 ms each there) timed
    against :data:`REFERENCE_LOOP_S`. At least 0.25: a fast machine still takes seconds."""
    took = []
    for _ in range(3):
        t0 = clock_s()
        for _ in range(iterations):
            pass
        took.append(clock_s() - t0)
    return max(0.25, sorted(took)[1] / (REFERENCE_LOOP_S * iterations / 1e6))


class Progress:
    """Stage lines on ``write`` (default: stderr, flushed), stamped with the time since
    ``start_s`` on ``clock_s``.

    ``quiet``: write nothing (a caller that prints its own lines). ``every_s``: how often a
    stage in progress is said again.
    """

    def __init__(self, write: Callable[[str], None] | None = None, clock_s: Callable[[], float] = time.monotonic,
                 start_s: float | None = None, every_s: float = 10.0, quiet: bool = False,
                 tag: str | None = None):
        self.write = write if write is not None else stderr_line
        self.clock_s = clock_s
        self.start_s = clock_s() if start_s is None else start_s
        self.every_s = float(every_s)
        self.quiet = quiet
        self.tag = tag
        """None: the daemon's event format; else lines ``TAG  12.3 s  text`` (a command
        that is no daemon: ``mavreg warm-up``)."""
        self.stages: list[tuple[str, float]] = []
        """(what, seconds) of every stage finished, in order (benchmarks and tests read it)."""

    def elapsed_s(self) -> float:
        return self.clock_s() - self.start_s

    def line(self, text: str) -> None:
        """One line in the daemon's event format, phase ``start`` (or with :attr:`tag`)."""
        if self.quiet:
            return
        if self.tag is None:
            self.write(f"daemon {self.elapsed_s():8.3f} s  {'':20s} [start] setup: {text}")
        else:
            self.write(f"{self.tag} {self.elapsed_s():6.1f} s  {text}")

    def stage(self, doing: str, done: str, announce: bool = True, late_s: float = 1.0) -> Stage:
        """A :class:`Stage` (a context manager, or :meth:`Stage.begin` and :meth:`Stage.end`):
        say ``doing`` at its start (or, with ``announce=False``, only if it lasts ``late_s``),
        again every ``every_s`` while it lasts, and ``done`` with its duration at its end (only
        if ``doing`` was said)."""
        return Stage(self, doing, done, announce, late_s)


class Stage:
    """One stage of a :class:`Progress` (:meth:`Progress.stage`); :meth:`end` is idempotent.
    An exception in a ``with`` block is not reported here: it propagates."""

    def __init__(self, progress: Progress, doing: str, done: str, announce: bool, late_s: float):
        self.progress, self.doing, self.done = progress, doing, done
        self.announce, self.late_s = announce, float(late_s)
        self._said = threading.Event()
        self._finished = threading.Event()
        self._ticker: threading.Thread | None = None
        self._t0 = math.nan

    def begin(self) -> Stage:
        p = self.progress
        self._t0 = p.clock_s()
        if self.announce:
            p.line(f"{self.doing} ...")
            self._said.set()
        self._ticker = threading.Thread(target=self._repeat, name="progress", daemon=True,
                                        args=(p.every_s if self.announce else self.late_s,))
        self._ticker.start()
        return self

    def end(self) -> None:
        if self._ticker is None or self._finished.is_set():
            return
        self._finished.set()
        self._ticker.join()
        p = self.progress
        took_s = p.clock_s() - self._t0
        p.stages.append((self.done, took_s))
        if self._said.is_set():
            p.line(f"{self.done} in {took_s:.1f} s")

    def __enter__(self) -> Stage:
        return self.begin()

    def __exit__(self, *exc) -> None:
        self.end()

    def _repeat(self, first_s: float) -> None:
        p = self.progress
        wait_s = first_s
        while not self._finished.wait(wait_s):
            if self._said.is_set():
                p.line(f"{self.doing} ({p.clock_s() - self._t0:.0f} s so far)")
            else:
                p.line(f"{self.doing} ...")
                self._said.set()
            wait_s = p.every_s


def stderr_line(text: str) -> None:
    """``text`` and its newline in one write (a stage line comes from another thread: two
    writes could interleave with the main thread's), flushed."""
    sys.stderr.write(text + "\n")
    sys.stderr.flush()
