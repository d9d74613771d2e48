"""Fly an experiment's runs over a process pool, with a progress line on stderr.

Every run is complete in its :class:`~.definitions.RunSpec` (seeds included), is flown by
one worker from scratch (each worker plans the maneuver once and keeps the plan), and comes
back as a :class:`RunOutcome`; the outcomes are put back in run order. ``sim`` runs that
the batch simulator flies (the paper's groups: :mod:`.via_batch`) are flown first, in this
process, in one compiled batch per plan, each record the sequential simulator's to 1e-9.
So the results depend on the experiment's seed alone, not on ``jobs`` nor on which worker finished first
(tests/unit/test_experiment_runner.py). ``jobs = 1`` flies in this process.

Workers are ``spawn``-ed processes bound to this one (:mod:`mavreg.daemon.jobs.lifeline`): they,
and the ``mavreg fly`` of a ``sitl`` run with its emulator, die with it however it ends; on
Ctrl-C they are killed at once. A run that raises is recorded with its error (one line, the
traceback apart) and the campaign goes on; a worker process that dies stops the campaign
(``BrokenProcessPool``).
"""
from __future__ import annotations

import functools
import multiprocessing
import os
import signal
import sys
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

from .definitions import DISTURBANCE, Experiment, RunSpec
from .disturbance_metrics import disturbance_metrics
from .metrics import run_metrics
from .record import Trace, truth_trace
from .robustness import ROBUSTNESS
from .robustness_metrics import judge_flight, robustness_metrics

__all__ = ["RunOutcome", "run_experiment", "plan_for", "VIAS", "TRACE_STEP"]

VIAS = ("sim", "sitl")
TRACE_STEP = 5
"""The figures get every 5th true sample (200 Hz of the 1 kHz records)."""


@dataclass(frozen=True)
class RunOutcome:
    """One run's numbers (:func:`~.metrics.run_metrics`), its decimated trace for the
    figures, or the error that stopped it."""

    spec: RunSpec
    metrics: dict | None
    trace: Trace | None
    error: str | None = None
    traceback: str | None = None

    @property
    def ok(self) -> bool:
        """The run met its experiment's criterion (converged, or stable)."""
        return self.metrics is not None and bool(self.metrics["ok"])


@dataclass(frozen=True)
class _Job:
    exp: Experiment
    spec: RunSpec
    via: str
    run_dir: Path | None
    sitl_files: object
    keep_flight_files: bool


@functools.lru_cache(maxsize=4)
def plan_for(maneuver_path: Path, vehicle_path: Path, controller_path: Path, laps: int):
    """The plan of a maneuver file flown ``laps`` times (cached per process)."""
    from ..config.controller import load_controller
    from ..config.vehicle import load_vehicle
    from ..planning.plan_io import plan_file
    return plan_file(maneuver_path, load_vehicle(vehicle_path), load_controller(controller_path), laps=laps)


def _plan_of(exp: Experiment, spec: RunSpec):
    maneuver = getattr(spec, "maneuver_path", None) or exp.maneuver_path    # robustness: the run's own
    return plan_for(Path(maneuver), Path(exp.vehicle_path), Path(exp.controller_path), spec.laps)


def _failed(spec: RunSpec, exc: Exception) -> RunOutcome:
    """A bug or a broken run: recorded with its error in one line, the campaign goes on."""
    first = str(exc).strip().splitlines()[:1] or [""]
    return RunOutcome(spec, None, None, f"{type(exc).__name__}: {first[0]}", traceback.format_exc())


def _judged(exp: Experiment, plan, spec: RunSpec, flight) -> RunOutcome:
    """The outcome of a flown run: its truth trace, its experiment's metrics."""
    trace = truth_trace(plan, flight)
    if exp.kind == ROBUSTNESS:
        metrics = robustness_metrics(plan, trace, flight, spec)
    elif exp.kind == DISTURBANCE:
        metrics = disturbance_metrics(plan, trace, flight, spec)
    else:
        metrics = run_metrics(plan, trace, flight, spec, exp.kind)
    return RunOutcome(spec, metrics, trace.decimated(TRACE_STEP))


def _execute(job: _Job) -> RunOutcome:
    spec = job.spec
    try:
        exp = job.exp
        plan = _plan_of(exp, spec)
        robust = exp.kind == ROBUSTNESS
        if job.via == "sim" and robust:
            from .robustness_sim import fly_robust_sim
            flight = fly_robust_sim(plan, spec, Path(exp.controller_path))
        elif job.via == "sim":
            from .via_sim import fly_sim
            flight = fly_sim(plan, spec, Path(exp.controller_path))
        else:
            from .via_sitl import fly_sitl
            flight = fly_sitl(spec, job.sitl_files, job.run_dir, plan.vehicle.max_rotor_thrust_n,
                              job.keep_flight_files, judge=judge_flight if robust else None)
        return _judged(exp, plan, spec, flight)
    except Exception as exc:
        return _failed(spec, exc)


def _fly_batched(exp: Experiment, todo: list, done) -> list:
    """Fly the ``sim`` jobs the batch simulator can fly (:mod:`.via_batch`) here, in batches,
    handing each outcome to ``done``; the jobs left for one at a time."""
    from ..config.controller import load_controller
    from .via_batch import batchable, fly_batches
    def plan_of(spec):
        return _plan_of(exp, spec)

    try:
        batch = [job for job in todo if batchable(exp, job.spec, plan_of)]
    except Exception:                              # a plan that fails fails its runs one by one
        return todo
    if not batch:
        return todo
    specs = [job.spec for job in batch]
    try:
        flown = fly_batches(specs, plan_of, load_controller(Path(exp.controller_path)))
    except Exception:          # a run the batch refuses (a bad inertia): each flown alone, its error its own
        return todo
    for spec, flight in flown:
        try:
            done(_judged(exp, _plan_of(exp, spec), spec, flight))
        except Exception as exc:
            done(_failed(spec, exc))
    return [job for job in todo if job not in batch]


def _init_worker(parent_pid: int) -> None:
    from ..daemon.jobs.lifeline import die_with_parent
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the parent's to handle
    die_with_parent(parent_pid)


class _Progress:
    """``NAME via VIA: done/total runs, failed, elapsed, left`` on one line (a line per run
    when the stream is not a terminal)."""

    def __init__(self, exp: Experiment, via: str, stream):
        self.head = f"{exp.name} via {via}"
        self.total = len(exp.runs)
        self.stream = stream
        self.tty = bool(stream is not None and hasattr(stream, "isatty") and stream.isatty())
        self.t0 = time.monotonic()
        self.done = self.failed = 0

    def update(self, out: RunOutcome) -> None:
        self.done += 1
        self.failed += 0 if out.ok else 1
        if self.stream is None:
            return
        el = time.monotonic() - self.t0
        left = el / self.done * (self.total - self.done)
        line = (f"{self.head}: {self.done}/{self.total} runs, {self.failed} not ok, {el:.0f} s elapsed"
                + (f", about {left:.0f} s left" if self.done < self.total else ""))
        if self.tty:
            self.stream.write("\r" + line.ljust(78) + ("\n" if self.done == self.total else ""))
        else:
            what = out.error if out.error else ("ok" if out.ok else "not ok")
            self.stream.write(f"{line} (run {out.spec.index}, {out.spec.label}: {what})\n")
        self.stream.flush()


def run_experiment(exp: Experiment, via: str, jobs: int, out_dir: Path | None = None,
                   progress=sys.stderr, keep_flight_files: bool = False,
                   dask_address: str | None = None) -> list[RunOutcome]:
    """Fly every run of ``exp`` ``via`` ``sim`` or ``sitl`` on ``jobs`` processes, or on the
    Dask cluster at ``dask_address`` (:mod:`.on_dask`; ``jobs`` is then unused).

    Parameters
    ----------
    exp : Experiment
    via : str
        ``sim`` (the design model) or ``sitl`` (the daemon and firmware_sim in lockstep).
    jobs : int
        Worker processes (at most one per run); 1 flies in this process.
    out_dir : Path, optional
        Where ``sitl`` runs write their flights (``runs/NNN/``) and the files they fly with;
        required for ``sitl``.
    progress : text stream or None
        Where the progress line goes.
    keep_flight_files : bool
        ``sitl``: keep each flight's tlog, control log and ground-truth recording.
    dask_address : str, optional
        A Dask scheduler's address (``tcp://host:8786``); None: the local process pool.

    Returns
    -------
    list of RunOutcome
        In run order.
    """
    if via not in VIAS:
        raise ValueError(f"unknown --via {via!r}; choose one of {', '.join(VIAS)}")
    if jobs < 1:
        raise ValueError(f"jobs must be at least 1, got {jobs}")
    if via == "sitl" and any(s.controller != "regulator" for s in exp.runs):
        raise ValueError("only maneuver regulation flies via sitl (the daemon flies the regulator); "
                         "the time-indexed trackers fly on the design model")
    files = None
    if out_dir is not None:
        out_dir = Path(out_dir).resolve()          # a sitl run's ``mavreg fly`` works in its own directory
    if via == "sitl":
        if out_dir is None:
            raise ValueError("a sitl campaign needs an output directory")
        from .via_sitl import prepare_sitl_files
        files = prepare_sitl_files(exp, Path(out_dir), 1 if dask_address is not None else jobs)
    todo = [_Job(exp, spec, via, None if out_dir is None else Path(out_dir) / "runs" / f"{spec.index:03d}",
                 files, keep_flight_files) for spec in exp.runs]
    bar = _Progress(exp, via, progress)
    outcomes: dict[int, RunOutcome] = {}

    def done(out: RunOutcome) -> None:
        outcomes[out.spec.index] = out
        bar.update(out)

    if via == "sim":
        todo = _fly_batched(exp, todo, done)
    jobs = min(jobs, len(todo))
    if todo and dask_address is not None:
        from .on_dask import run_on_dask
        run_on_dask(dask_address, exp, todo, _execute, done, Path(out_dir) if via == "sitl" else None)
    elif jobs <= 1:
        for job in todo:
            done(_execute(job))
    else:
        pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_worker, initargs=(os.getpid(),))
        try:
            for fut in as_completed([pool.submit(_execute, job) for job in todo]):
                done(fut.result())                 # a worker that died: BrokenProcessPool
        except BaseException:                      # Ctrl-C, a dead worker: stop the others now
            for proc in list((getattr(pool, "_processes", None) or {}).values()):
                proc.kill()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown()
    return [outcomes[spec.index] for spec in exp.runs]
