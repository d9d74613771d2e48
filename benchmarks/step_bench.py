"""The controller step (state in, rotor commands out) over the states of closed-loop barrel rolls.

``run_step(quick)`` returns figures (:func:`benchmarks.io_helpers.figure`):
``step_us.p50``, ``step_us.p99``, ``step_us.p999``: microseconds per call of the production
step, :meth:`mavreg.control.controllers.regulator.ManeuverRegulator.step` (the paper's design,
``paper_lqr.yaml``; a 1 kHz control period and the vehicle's rotor lag in the feedforward's
lead, as the daemon builds it), over 30 000 states (quick: 3 000) in flight order: the
first group 1 runs of the paper (0.6 m off in each axis, nominal then drawn inertia) flown
on the design model by :func:`mavreg.sim.batch.fly_batch`, one after the other, the
regulator reset (untimed) at the start of each. Baseline, same states, same run, the two
steps taken in turn on each state: :class:`harness.plain_regulator.PlainRegulator`, the
straightforward step with scipy interpolators and small numpy arrays (it agrees to 1e-9).

Run alone: ``python -m benchmarks.step_bench [--quick]``.
"""
from __future__ import annotations

import time

import numpy as np

from benchmarks.io_helpers import BARREL, PAPER_CONTROLLER, VEHICLE, figure
from harness.plain_regulator import PlainRegulator
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.experiments.definitions import paper_group1
from mavreg.planning.plan_io import plan_file
from mavreg.sim.batch import BatchRun, fly_batch

__all__ = ["run_step", "closed_loop_states", "time_steps"]

CONTROL_PERIOD_S = 1e-3
TARGETS_US = {"p50": 12.0, "p99": 25.0, "p999": None}


def closed_loop_states(plan, n: int) -> tuple[np.ndarray, list[int]]:
    """``n`` states (n, 12) the regulator saw in group 1 runs flown one after the other, and
    the index where each run starts."""
    specs = paper_group1(seed=0).runs
    runs = [BatchRun(r.offset_m, r.inertia_kg_m2, r.rotor_noise_sd_n, r.saturation_n, r.seed) for r in specs]
    per_run = int(plan.duration_s * 1000) + 1
    results = fly_batch(plan, runs[:-(-n // per_run)])
    states = [r.x[:r.controller_calls] for r in results]
    starts = list(np.cumsum([0] + [len(x) for x in states[:-1]]))
    return np.concatenate(states)[:n], [s for s in starts if s < n]


def time_steps(regulators, states: np.ndarray, starts: list[int]) -> np.ndarray:
    """Seconds per ``step(x)`` of each regulator (columns) over ``states`` in order, taken in
    turn on each state so that the machine's load falls on all alike (reset, untimed, at
    ``starts``)."""
    out = np.empty((len(states), len(regulators)))
    clock, begin = time.perf_counter, set(starts)
    steps = [r.step for r in regulators]
    for i, x in enumerate(states):
        if i in begin:
            for r in regulators:
                r.reset(x)
        for j, step in enumerate(steps):
            t0 = clock()
            step(x)
            out[i, j] = clock() - t0
    return out


def run_step(quick: bool) -> dict:
    """All the figures of the module docstring."""
    vehicle = load_vehicle(VEHICLE)
    plan = plan_file(BARREL, vehicle, load_controller(PAPER_CONTROLLER))
    n = 3000 if quick else 30_000
    states, starts = closed_loop_states(plan, n)
    states = list(states)                       # rows as the daemon hands them: one array a step
    times = time_steps([ManeuverRegulator(plan, vehicle, control_period_s=CONTROL_PERIOD_S),
                        PlainRegulator(plan, vehicle, control_period_s=CONTROL_PERIOD_S)], states, starts)
    fast, plain = times[:, 0], times[:, 1]
    note = (f"ManeuverRegulator.step over {len(states)} closed-loop states of {len(starts)} group 1 barrel "
            "roll(s) (paper_lqr.yaml); baseline: the plain step (scipy interp1d, small numpy arrays)")
    return {f"step_us.{name}": figure(float(np.percentile(fast, q)) * 1e6, float(np.percentile(plain, q)) * 1e6,
                                      target=TARGETS_US[name], unit="us", higher_is_better=False, note=note)
            for name, q in (("p50", 50.0), ("p99", 99.0), ("p999", 99.9))}


if __name__ == "__main__":
    from benchmarks.report import standalone
    standalone(run_step, __doc__)
