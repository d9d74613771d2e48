"""Fly a ``--via sim`` campaign's runs in compiled batches, one per plan and regulator.

The runs of the paper's groups differ only by what :class:`~mavreg.sim.batch.BatchRun`
holds (start offset, plant inertia, rotor noise, saturation, seed) and share a plan. The
batch simulator (:func:`mavreg.sim.batch.fly_batch`) flies them together, each run's record
the sequential simulator's to 1e-9 (``tests/unit/test_batch_sim.py``), at a few
hundredths of a second a run instead of seconds. A run it cannot fly goes to
:func:`~.via_sim.fly_sim` one at a time: a time-indexed tracker, a gust, a start inside the
maneuver, a set duration, lag-aware gains, a robustness campaign (its realistic-like world),
or where numba is not in use.

Runs batch together when they share the plan (maneuver and laps), the regulator as the
controller file and the told rotor limit make it, and the time allowed. Pure: plans in,
records out.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from .. import accel
from ..config.controller import ControllerParams
from ..config.regulation import told_rotor_limit
from ..sim.batch import BatchRun, fly_batch
from .definitions import REGULATOR, Experiment, RunSpec
from .record import Flight
from .robustness import ROBUSTNESS
from .via_sim import CONTROL_PERIOD_S, flight_from_result, max_time_s

__all__ = ["batchable", "fly_batches", "BatchGroup"]


@dataclass(frozen=True)
class BatchGroup:
    """Runs that fly in one batch: their plan's key, the regulator's settings, the time allowed."""

    maneuver_path: Path
    laps: int
    told_limit_n: float | None
    extra_time_s: float


def batchable(exp: Experiment, spec: RunSpec, plan_of: Callable[[RunSpec], object]) -> bool:
    """Whether the batch simulator flies ``spec`` as :func:`~.via_sim.fly_sim` would
    (``plan_of(spec)``, its plan, is asked for last: only a run that could batch is planned)."""
    return (accel.ACCELERATED and exp.kind != ROBUSTNESS
            and spec.controller == REGULATOR and spec.gust_force_n is None and not spec.start_s_m
            and spec.max_time_s is None and plan_of(spec).K.shape[-1] == 11)


def _group(exp: Experiment, spec: RunSpec, plan) -> BatchGroup:
    maneuver = Path(getattr(spec, "maneuver_path", None) or exp.maneuver_path)
    return BatchGroup(maneuver, spec.laps, spec.saturation_n, max_time_s(plan, spec) - plan.duration_s)


def fly_batches(exp: Experiment, specs: Sequence[RunSpec], plan_of: Callable[[RunSpec], object],
                controller: ControllerParams) -> list[tuple[RunSpec, Flight]]:
    """Fly ``specs`` (each :func:`batchable`) in batches; (spec, flight) in ``specs``' order.

    ``plan_of(spec)`` gives a run's plan; ``controller`` is the campaign's controller file,
    whose allocation (told each run's rotor limit) and speed governor the regulator takes.
    """
    groups: dict[BatchGroup, list[RunSpec]] = {}
    for spec in specs:
        groups.setdefault(_group(exp, spec, plan_of(spec)), []).append(spec)
    flown: dict[int, Flight] = {}
    for key, members in groups.items():
        plan = plan_of(members[0])
        runs = [BatchRun(tuple(s.offset_m), s.inertia_kg_m2, s.rotor_noise_sd_n, s.saturation_n, s.seed)
                for s in members]
        results = fly_batch(plan, runs, control_rate_hz=1.0 / CONTROL_PERIOD_S, dt_s=CONTROL_PERIOD_S,
                            extra_time_s=key.extra_time_s, compiled=True,
                            allocation=told_rotor_limit(controller.allocation, key.told_limit_n),
                            speed_governor=controller.speed_governor)
        for spec, res in zip(members, results):
            flown[spec.index] = flight_from_result(res, spec.saturation_n)
    return [(spec, flown[spec.index]) for spec in specs]
