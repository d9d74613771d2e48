"""Planning off the event loop, in a worker process at the lowest CPU priority.

Planning (loader, nominal, feasibility, Riccati sweep) is seconds of CPU-bound Python
that holds the GIL, so a thread would stall the control loop; it runs in a
:class:`concurrent.futures.ProcessPoolExecutor` (one worker, ``spawn`` context, so the
worker shares no sockets or event loop with the daemon) through ``loop.run_in_executor``.
The worker plans with the vehicle and controller parameters the daemon loaded (frozen
dataclasses, pickled with each upload: a restarted worker cannot read a file edited since the
daemon started, so planner and regulator use the same parameters) and returns the picklable Plan with
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

Bounds (:class:`PlannerBounds`), so that a hostile upload (an alias bomb, a maneuver
kilometres long) costs at most a rejection and never the daemon:

- **memory**: after warming up, the worker limits its own address space
  (``RLIMIT_AS``) to what it then uses plus ``memory_bytes``; an allocation beyond it
  raises ``MemoryError`` in the worker, which rejects the upload; the worker is then
  replaced (the heap it grew stays mapped, and the next plan would fail there too);
- **CPU**: each plan may use ``cpu_s`` seconds of the worker's CPU time (a profiling
  interval timer, ``ITIMER_PROF``, counts CPU, not the waiting a ``SCHED_IDLE`` worker
  does on a busy machine); beyond it the plan is abandoned and the upload rejected;
- **wall clock**: a plan not answered within ``wall_s`` (the worker hangs in C code, or is
  stopped) gets its worker killed and replaced, and the upload rejected;
- **result size**: a plan whose pickle exceeds ``result_bytes`` is rejected in the worker,
  before it is sent: unpickling it would hold the daemon's interpreter lock;
- **one plan at a time**: uploads wait their turn (at most ``queue`` of them; more are
  rejected at once), so the wall clock of one is not spent waiting for another.

Every rejection reason is one line of at most :data:`mavreg.errors.MAX_MESSAGE_CHARS`
characters (a loader message that quotes an expanded alias cannot make it megabytes).
"""
from __future__ import annotations

import asyncio
import multiprocessing
import os
import pickle
import signal
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ...errors import EXIT_FAILED, exit_status_of, one_line
from .lifeline import die_with_parent
from .pool_workers import how_it_ended, stop_pool, workers

if TYPE_CHECKING:
    from ...config.controller import ControllerParams
    from ...config.vehicle import VehicleParams

__all__ = ["PlanResult", "PlannerPool", "PlannerDied", "PlannerBounds", "plan_in_worker", "lower_priority"]

_MIB = 1024 * 1024


@dataclass(frozen=True)
class PlannerBounds:
    """What one upload may cost the planner worker (module docstring, "Bounds")."""

    memory_bytes: int = 1536 * _MIB
    """Address space the worker may add to what it uses once warm (about 570 MB; planning the
    barrel roll adds about 270 MB)."""
    cpu_s: float = 60.0
    """CPU seconds per plan (the barrel roll with its margins: about 6 s)."""
    wall_s: float = 600.0
    """Wall seconds per plan before the worker is killed and replaced (the worker runs at the
    lowest priority: on a busy machine it waits)."""
    result_bytes: int = 96 * _MIB
    """Largest pickled plan sent back: unpickling it holds the daemon's interpreter lock, about
    20 ms for the library's maneuvers (22-35 MiB: barrel roll 22, climbing helix 35), so at
    most about 60 ms for a plan at this cap."""
    queue: int = 4
    """Uploads that may wait for the worker; more are rejected at once."""


@dataclass(frozen=True)
class PlanResult:
    """A plan, or the reason there is none (one line) and the exit status it means
    (:mod:`mavreg.errors`: 2 a bad file, 1 a maneuver that cannot be flown or planned)."""

    plan: object | None
    reason: str = ""
    status: int = 0
    retire_worker: bool = False
    """The worker hit its memory bound: replace it before the next plan."""

    @property
    def accepted(self) -> bool:
        return self.plan is not None


class PlannerDied(RuntimeError):
    """The worker process died while planning; the pool has been restarted."""


class _OverCpuBudget(BaseException):
    """Raised in the worker by the CPU timer's signal (not an Exception: a library's ``except
    Exception`` does not swallow it)."""


def _over_cpu_budget(signum, frame):
    raise _OverCpuBudget()


def _over_memory(source: str, bounds: PlannerBounds) -> PlanResult:
    """The rejection of a plan that hit the worker's memory bound (the worker is replaced)."""
    return PlanResult(None, f"{source}: planning needed more than the planner's "
                      f"{bounds.memory_bytes / _MIB:.0f} MiB of memory and was abandoned", EXIT_FAILED,
                      retire_worker=True)


def plan_in_worker(yaml_text: str, source: str, vehicle: VehicleParams, controller: ControllerParams,
                   bounds: PlannerBounds = PlannerBounds()) -> PlanResult:
    """Validate and plan one maneuver, with its margins (runs in the worker process).

    An anticipated error (:func:`mavreg.errors.exit_status_of`: the loader's, the
    planner's), the memory and CPU bounds and the result size give a rejection; any other
    exception propagates (a bug: the daemon logs its traceback and answers an error).
    """
    _warm(bounds.memory_bytes)   # a replaced worker: bounded too
    old = signal.signal(signal.SIGPROF, _over_cpu_budget)
    signal.setitimer(signal.ITIMER_PROF, bounds.cpu_s)
    try:
        try:
            return _plan_checked(yaml_text, source, vehicle, controller, bounds)
        finally:
            signal.setitimer(signal.ITIMER_PROF, 0)
    except _OverCpuBudget:
        return PlanResult(None, f"{source}: planning used more than its {bounds.cpu_s:g} s of CPU "
                          "and was abandoned", EXIT_FAILED)
    except MemoryError:
        return _over_memory(source, bounds)
    except Exception as exc:
        status = exit_status_of(exc)
        if status is None:
            raise
        return PlanResult(None, one_line(exc), status)
    finally:
        signal.signal(signal.SIGPROF, old)


def _plan_checked(yaml_text, source, vehicle, controller, bounds) -> PlanResult:
    from ...planning.plan_io import plan_text
    from ...control.controllers.hover import HoverParams
    from ...maneuver.plan_margins import with_margins
    plan = with_margins(plan_text(yaml_text, source, vehicle, controller), HoverParams.from_controller(controller))
    size = len(pickle.dumps(plan, protocol=pickle.HIGHEST_PROTOCOL))
    if size > bounds.result_bytes:
        return PlanResult(None, f"{source}: the plan takes {size / _MIB:.0f} MiB, more than the "
                          f"{bounds.result_bytes / _MIB:.0f} MiB a daemon takes (fewer laps, a shorter "
                          "maneuver)", EXIT_FAILED)
    return PlanResult(plan)


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


_LIMITED: list[int | None] = []


def _warm(memory_bytes: int) -> int:
    """Import the planner, then bound the address space (once per worker)."""
    import mavreg.maneuver.plan  # noqa: F401  (import cost paid before the first upload)
    import mavreg.maneuver.plan_margins  # noqa: F401
    if not _LIMITED:
        _LIMITED.append(limit_address_space(memory_bytes))
    return os.getpid()


def limit_address_space(extra_bytes: int) -> int | None:
    """Limit this process's address space to its current size plus ``extra_bytes``.

    Returns the limit set (bytes), or None where ``RLIMIT_AS`` or ``/proc`` is missing.
    """
    try:
        import resource
        with open("/proc/self/statm") as f:
            size = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
    except (ImportError, OSError, ValueError):
        return None
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = size + int(extra_bytes)
    if hard != resource.RLIM_INFINITY:
        limit = min(limit, hard)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    return limit


class PlannerPool:
    """One planning worker process shared by every upload.

    Parameters
    ----------
    vehicle : mavreg.config.vehicle.VehicleParams
        The vehicle the daemon flies (as loaded; the worker gets a pickled copy with each upload).
    controller : mavreg.config.controller.ControllerParams
        The controller file's parameters, as loaded by the daemon.
    bounds : PlannerBounds, optional
        What one upload may cost (module docstring).
    """

    def __init__(self, vehicle: VehicleParams, controller: ControllerParams,
                 bounds: PlannerBounds = PlannerBounds()):
        self.vehicle = vehicle
        self.controller = controller
        self.bounds = bounds
        self._pool = self._new_executor()
        self._turn = asyncio.Lock()
        self.busy = 0
        self.restarts = 0
        self.timeouts = 0
        """Plans whose worker was killed for the wall-clock bound."""
        self._closed = False
        self.worker_pid: int | None = None
        """The worker's pid once :meth:`warm_up` has run (None before)."""
        self._worker_procs: list = []
        """Its process, kept to read how it ended (the executor forgets a dead worker)."""

    @staticmethod
    def _new_executor() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker, initargs=(os.getpid(),))

    async def warm_up(self) -> None:
        """Start the worker and import the planner, so the first upload plans at once."""
        loop = asyncio.get_running_loop()
        self.worker_pid = await loop.run_in_executor(self._pool, _warm, self.bounds.memory_bytes)
        self._worker_procs = workers(self._pool)

    async def plan(self, yaml_text: str, source: str) -> PlanResult:
        """Plan one upload in the worker.

        Raises
        ------
        PlannerDied
            The worker died while planning; a new one is ready for the next upload.
        """
        if self._closed:
            raise PlannerDied("the planner has been shut down (the daemon is stopping)")
        if self.busy > self.bounds.queue:
            return PlanResult(None, f"{source}: the planner is busy with {self.busy} uploads; "
                              "upload again later", EXIT_FAILED)
        self.busy += 1
        try:
            async with self._turn:
                return await self._plan_now(yaml_text, source)
        finally:
            self.busy -= 1

    async def _plan_now(self, yaml_text: str, source: str) -> PlanResult:
        if self.worker_pid is None:     # a replaced worker starts outside the plan's wall clock
            try:
                await self.warm_up()
            except BrokenProcessPool:
                self._restart()
        loop = asyncio.get_running_loop()
        args = (plan_in_worker, yaml_text, source, self.vehicle, self.controller, self.bounds)
        try:
            try:
                future = loop.run_in_executor(self._pool, *args)
            except BrokenProcessPool:   # died while idle: nothing of this upload ran yet
                self._restart()
                future = loop.run_in_executor(self._pool, *args)
            try:
                result = await asyncio.wait_for(future, self.bounds.wall_s)
            except MemoryError:         # the bound hit outside the plan: sending its result back
                result = _over_memory(source, self.bounds)
            except asyncio.TimeoutError:
                self.timeouts += 1
                self._restart()
                return PlanResult(None, f"{source}: no plan within {self.bounds.wall_s:g} s; the planner "
                                  "worker was stopped and replaced", EXIT_FAILED)
            if result.retire_worker:
                self._restart()
            return result
        except BrokenProcessPool as exc:
            if self._closed:
                raise PlannerDied("the planner was shut down while planning (the daemon is stopping)") from exc
            how = how_it_ended(self._worker_procs or workers(self._pool))
            self._restart()
            raise PlannerDied(f"the planner worker process died while planning {source!r} ({how}); "
                              "the upload is refused and nothing else changed; a new worker was started: "
                              "upload again") from exc

    def _restart(self) -> None:
        stop_pool(self._pool)
        self._pool = self._new_executor()
        self.worker_pid, self._worker_procs = None, []
        self.restarts += 1

    def shutdown(self) -> None:
        """Kill the worker (a plan in progress is abandoned) and release the executor."""
        self._closed = True
        stop_pool(self._pool)
