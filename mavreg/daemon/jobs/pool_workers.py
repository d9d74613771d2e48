"""The worker processes of a :class:`concurrent.futures.ProcessPoolExecutor`: read while they
live, told how they ended, killed (the planner's, :mod:`mavreg.daemon.jobs.planner_pool`)."""
from __future__ import annotations

import signal
import time
from concurrent.futures import ProcessPoolExecutor

__all__ = ["workers", "how_it_ended", "stop_pool"]


def workers(pool: ProcessPoolExecutor) -> list:
    """The executor's worker processes (CPython keeps them in ``_processes``; a broken pool's
    manager thread may clear that at any moment, so they are taken while the worker lives)."""
    return list((getattr(pool, "_processes", None) or {}).values())


def how_it_ended(procs: list) -> str:
    """How the broken executor's worker ``procs`` ended: ``killed by SIGKILL``, ``exit status
    1``; what is known."""
    code = None
    for proc in procs:
        try:
            proc.join(1.0)          # broken: it is dead or dying (its pipe closed first)
            for _ in range(40):     # the executor's thread may be reaping it this instant
                if proc.exitcode is not None:
                    code = proc.exitcode
                    break
                time.sleep(0.005)
        except (OSError, ValueError, AssertionError, AttributeError):
            pass
    if code is None:
        return "killed or out of memory"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit status {code}"


def stop_pool(pool: ProcessPoolExecutor) -> None:
    """Kill the executor's worker and release the executor (a plan in progress is abandoned)."""
    # Kill the workers rather than wait (3.14 adds kill_workers()): at exit the interpreter
    # would join a worker still planning.
    procs = workers(pool)
    pool.shutdown(wait=False, cancel_futures=True)
    for act in (lambda p: p.kill(), lambda p: p.join(5.0)):
        for proc in procs:
            try:
                act(proc)
            except (OSError, ValueError, AssertionError, AttributeError):
                pass
