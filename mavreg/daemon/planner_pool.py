"""Planning off the event loop, in a worker process at the lowest CPU priority.

Planning (loader, nominal, feasibility, Riccati sweep) is seconds of CPU-bound Python
that holds the GIL, so a thread would stall the control loop; it runs in a
:class:`concurrent.futures.ProcessPoolExecutor` (one worker, ``spawn`` context, so the
worker shares no sockets or event loop with the daemon) through ``loop.run_in_executor``.
The worker loads the vehicle and controller files once and returns the picklable Plan with
its delay and gain margins (:func:`~mavreg.maneuver.plan_margins.with_margins`, which the
health gate holds the link to), or the one-line reason a user error (ConfigError,
ManeuverError) gave.

The worker's initializer (:func:`_init_worker`):

- drops every thread of the worker (BLAS threads included) to the lowest priority:
  ``nice`` 19 and, on Linux, ``SCHED_IDLE`` (it runs only on CPU time nobody else wants),
  so on a 2-core machine planning never starves the control loop or an emulator;
  failures to lower the priority are ignored;
- ignores SIGINT: Ctrl-C in a terminal reaches the whole process group, and what it
  means (land, then stop) is the daemon's decision, not the worker's;
- ties the worker's life to the daemon's (:mod:`.lifeline`: parent-death SIGKILL on
  Linux and a watcher of ``os.getppid()``), so no worker survives the daemon, even a
  SIGKILLed one.

A worker that dies (killed, out of memory) breaks the executor: :meth:`PlannerPool.plan`
then starts a fresh executor and raises :class:`PlannerDied`; the next upload plans on
the new worker. :meth:`PlannerPool.shutdown` kills the worker rather than waiting for a
plan nobody will use.
"""
from __future__ import annotations

import asyncio
import multiprocessing
import os
import signal
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path

from .lifeline import die_with_parent

__all__ = ["PlanResult", "PlannerPool", "PlannerDied", "plan_in_worker", "lower_priority"]

_CACHE: dict = {}


@dataclass(frozen=True)
class PlanResult:
    """A plan, or the reason there is none."""

    plan: object | None
    reason: str = ""

    @property
    def accepted(self) -> bool:
        return self.plan is not None


class PlannerDied(RuntimeError):
    """The worker process died while planning; the pool has been restarted."""


def _params(vehicle_path: str, controller_path: str):
    key = (vehicle_path, controller_path)
    if key not in _CACHE:
        from ..config.controller import load_controller
        from ..config.vehicle import load_vehicle
        _CACHE[key] = (load_vehicle(vehicle_path), load_controller(controller_path))
    return _CACHE[key]


def plan_in_worker(yaml_text: str, source: str, vehicle_path: str, controller_path: str) -> PlanResult:
    """Validate and plan one maneuver, with its margins (runs in the worker process)."""
    from ..maneuver.plan import plan_text
    from ..maneuver.plan_margins import with_margins
    try:
        vehicle, controller = _params(vehicle_path, controller_path)
        return PlanResult(with_margins(plan_text(yaml_text, source, vehicle, controller)))
    except ValueError as exc:   # ConfigError, ManeuverError: the user's file is at fault
        return PlanResult(None, " ".join(str(exc).split()))


def _thread_ids() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        return []


def lower_priority() -> dict:
    """Put every thread of this process at nice 19 and, on Linux, ``SCHED_IDLE``.

    Threads started later inherit the setting from the thread that starts them. Linux
    applies nice and scheduling policy per thread, hence the walk over
    ``/proc/self/task`` (a worker may already run BLAS threads when this is called).

    Returns
    -------
    dict
        ``{"nice": int, "sched_idle": bool}`` as achieved for the calling thread.
    """
    try:
        os.nice(19)
    except OSError:
        pass
    sched_idle = False
    policy = getattr(os, "SCHED_IDLE", None)
    for tid in _thread_ids():
        try:
            os.setpriority(os.PRIO_PROCESS, tid, 19)
        except OSError:
            pass
        if policy is not None:
            try:
                os.sched_setscheduler(tid, policy, os.sched_param(0))
            except OSError:
                pass
    if policy is not None:
        try:
            sched_idle = os.sched_getscheduler(0) == policy
        except OSError:
            sched_idle = False
    return {"nice": os.getpriority(os.PRIO_PROCESS, 0), "sched_idle": sched_idle}


def _init_worker(parent_pid: int) -> None:
    """Worker initializer: lowest priority, SIGINT ignored, dies with the daemon."""
    die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    lower_priority()


def _warm(vehicle_path: str, controller_path: str) -> int:
    _params(vehicle_path, controller_path)
    import mavreg.maneuver.plan  # noqa: F401  (import cost paid before the first upload)
    return os.getpid()


class PlannerPool:
    """One planning worker process shared by every upload.

    Parameters
    ----------
    vehicle_path, controller_path : str or Path
        Parameter files the worker loads once.
    """

    def __init__(self, vehicle_path: str | Path, controller_path: str | Path):
        self.vehicle_path = str(vehicle_path)
        self.controller_path = str(controller_path)
        self._pool = self._new_executor()
        self.busy = 0
        self.restarts = 0
        self._closed = False
        self.worker_pid: int | None = None
        """The worker's pid once :meth:`warm_up` has run (None before)."""

    @staticmethod
    def _new_executor() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker, initargs=(os.getpid(),))

    async def warm_up(self) -> None:
        """Start the worker and import the planner, so the first upload plans at once."""
        loop = asyncio.get_running_loop()
        self.worker_pid = await loop.run_in_executor(self._pool, _warm, self.vehicle_path,
                                                     self.controller_path)

    async def plan(self, yaml_text: str, source: str) -> PlanResult:
        """Plan one upload in the worker.

        Raises
        ------
        PlannerDied
            The worker died while planning; a new one is ready for the next upload.
        """
        if self._closed:
            raise PlannerDied("the planner has been shut down (the daemon is stopping)")
        loop = asyncio.get_running_loop()
        args = (plan_in_worker, yaml_text, source, self.vehicle_path, self.controller_path)
        self.busy += 1
        try:
            try:
                future = loop.run_in_executor(self._pool, *args)
            except BrokenProcessPool:   # died while idle: nothing of this upload ran yet
                self._restart()
                future = loop.run_in_executor(self._pool, *args)
            return await future
        except BrokenProcessPool as exc:
            if self._closed:
                raise PlannerDied("the planner was shut down while planning (the daemon is stopping)") from exc
            self._restart()
            raise PlannerDied(f"the planner worker process died while planning {source!r} "
                              f"(killed or out of memory); a new worker was started: upload again") from exc
        finally:
            self.busy -= 1

    def _restart(self) -> None:
        self._stop(self._pool)
        self._pool = self._new_executor()
        self.worker_pid = None
        self.restarts += 1

    @staticmethod
    def _stop(pool: ProcessPoolExecutor) -> None:
        # CPython keeps the workers in ``_processes`` (3.14 adds kill_workers()); kill them
        # rather than wait: at exit the interpreter would join a worker still planning.
        procs = list((getattr(pool, "_processes", None) or {}).values())
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            try:
                proc.kill()
            except (OSError, ValueError, AttributeError):
                pass
        for proc in procs:
            try:
                proc.join(5.0)
            except (OSError, ValueError, AssertionError, AttributeError):
                pass

    def shutdown(self) -> None:
        """Kill the worker (a plan in progress is abandoned) and release the executor."""
        self._closed = True
        self._stop(self._pool)
