"""Fly a ``--via sim`` campaign's runs in compiled batches, one per plan and regulator.

The runs of the paper's groups differ only by what :class:`~mavreg.sim.batch.BatchRun`
holds (start offset, plant inertia, rotor noise, saturation, seed) and share a plan. The
batch simulator (:func:`mavreg.sim.batch.fly_batch`) flies them together, each run's record
the sequential simulator's to 1e-9 (``tests/unit/test_batch_sim.py``), at a few
hundredths of a second a run instead of seconds. A run it cannot fly goes to
:func:`~.via_sim.fly_sim` one at a time: a time-indexed tracker, a gust, a start inside the
maneuver, a set duration, lag-aware gains, a robustness campaign (its realistic-like world),
or where numba is not in use.

Runs batch together when they share the plan (the same plan object: maneuver and laps), the
regulator as the controller file and the told rotor limit make it, and the time allowed. Pure: plans in,
records out.
"""
from __future__ import annotations

from typing import Callable, Sequence

from .. import accel
from ..config.controller import ControllerParams
from ..config.regulation import told_rotor_limit
from ..sim.batch import BatchRun, fly_batch
from .definitions import REGULATOR, Experiment, RunSpec
from .record import Flight
from .robustness import ROBUSTNESS
from .via_sim import CONTROL_PERIOD_S, flight_from_result, max_time_s

__all__ = ["batchable", "fly_batches"]


def batchable(exp: Experiment, spec: RunSpec, plan_of: Callable[[RunSpec], object]) -> bool:
    """Whether the batch simulator flies ``spec`` as :func:`~.via_sim.fly_sim` would
    (``plan_of(spec)``, its plan, is asked for last: only a run that could batch is planned)."""
    return (accel.ACCELERATED and exp.kind != ROBUSTNESS
            and spec.controller == REGULATOR and spec.gust_force_n is None and not spec.start_s_m
            and spec.max_time_s is None and plan_of(spec).K.shape[-1] == 11)


def fly_batches(specs: Sequence[RunSpec], plan_of: Callable[[RunSpec], object],
                controller: ControllerParams) -> list[tuple[RunSpec, Flight]]:
    """Fly ``specs`` (each :func:`batchable`) in batches; (spec, flight) in ``specs``' order.

    ``plan_of(spec)`` gives a run's plan (the same object for the runs that share it);
    ``controller`` is the campaign's controller file, whose allocation (told each run's rotor
    limit) and speed governor the regulator takes.
    """
    groups: dict[tuple, tuple[object, list[RunSpec]]] = {}
    for spec in specs:
        plan = plan_of(spec)
        key = (id(plan), spec.saturation_n, max_time_s(plan, spec) - plan.duration_s)
        groups.setdefault(key, (plan, []))[1].append(spec)
    flown: dict[int, Flight] = {}
    for (_, told_limit_n, extra_time_s), (plan, members) in groups.items():
        runs = [BatchRun(tuple(s.offset_m), s.inertia_kg_m2, s.rotor_noise_sd_n, s.saturation_n, s.seed)
                for s in members]
        results = fly_batch(plan, runs, control_rate_hz=1.0 / CONTROL_PERIOD_S, dt_s=CONTROL_PERIOD_S,
                            extra_time_s=extra_time_s, compiled=True,
                            allocation=told_rotor_limit(controller.allocation, told_limit_n),
                            speed_governor=controller.speed_governor)
        for spec, res in zip(members, results):
            flown[spec.index] = flight_from_result(res, spec.saturation_n)
    return [(spec, flown[spec.index]) for spec in specs]
