"""The controller step (state in, rotor commands out) over the states of closed-loop barrel rolls.

Run: ``python benchmarks/bench_step.py [--states N] [--repeat K]``. For each controller file
(``paper_lqr.yaml``, and ``realistic.yaml`` with the rotor forces and a disturbance estimate
as the daemon hands them over) it flies the barrel roll on the design model, keeps the
states the regulator saw, then times :meth:`ManeuverRegulator.step` on them, in order, one
call per state (the projection is warm-started from the previous one), the numpy step and
the compiled one (``compiled=``), and prints p50, p99, p99.9 and the maximum, and the time
the kernel took to compile or load. Asserts nothing (shared machines are noisy). The
regulators are built as the controller files say (allocation, speed governor). The suite's
step figure (``python -m benchmarks``) is the paper file's alone.

Also importable: :func:`closed_loop_states` gives the states, :func:`time_steps` the timings.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mavreg.config.paths import PARAMS_DIR
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.control.controllers import fastpath
from mavreg.control.estimation.disturbance import DisturbanceEstimate
from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.planning.plan_io import plan_file
from mavreg.sim.maneuver_run import fly_on_design_model

ROOT = Path(__file__).resolve().parents[1]
MANEUVER = PARAMS_DIR / "maneuvers/barrel_roll.yaml"
VEHICLE = PARAMS_DIR / "vehicles/mk_quadro.yaml"
CONTROL_RATE_HZ = 1000.0
OFFSETS_M = ((0.05, -0.05, 0.05), (-0.1, 0.1, 0.0), (0.0, 0.15, -0.1))
"""Start offsets of the flights whose states are collected, one flight after the other."""
ESTIMATE = DisturbanceEstimate((0.35, 0.12), (0.6, -0.4, 0.3), 0.97)
"""A disturbance estimate as the daemon's observer gives it in flight on the realistic world
(drag near RotorPy's, a light steady wind force, a sagging thrust scale)."""


@dataclass(frozen=True)
class StepCase:
    """One controller file's regulator and the arguments of its steps."""

    name: str
    plan: object
    vehicle: object
    controller: object
    states: np.ndarray
    """(n, 12) states, in flight order."""
    rotor_forces_n: np.ndarray | None
    """(n, 4) rotor forces handed over with each state (lag-aware gains), or None."""
    starts: np.ndarray
    """Indices where a new flight starts (the regulator is reset there, untimed)."""
    disturbance: DisturbanceEstimate | None

    def regulator(self, **kwargs) -> ManeuverRegulator:
        c = self.controller
        return ManeuverRegulator(self.plan, self.vehicle, control_period_s=1.0 / CONTROL_RATE_HZ,
                                 max_compensation_turn_rad=c.disturbance.max_compensation_turn_rad,
                                 allocation=c.allocation, speed_governor=c.speed_governor, **kwargs)


def closed_loop_states(controller_name: str, n_states: int = 30_000) -> StepCase:
    """The states of barrel rolls flown on the design model with ``controller_name``'s plan.

    Flights start at :data:`OFFSETS_M` in turn until ``n_states`` control steps are
    collected. The realistic file's flights have the 20 ms rotor lag (the regulator is handed
    the lagged rotor forces) and its steps the disturbance estimate :data:`ESTIMATE`.
    """
    vehicle = load_vehicle(VEHICLE)
    controller = load_controller(PARAMS_DIR / f"controller/{controller_name}.yaml")
    plan = plan_file(MANEUVER, vehicle, controller)
    lagged = plan.rotor_time_constant_s > 0
    xs, fs, starts = [], [], []
    k = 0
    while sum(len(x) for x in xs) < n_states:
        run = fly_on_design_model(plan, offset_m=OFFSETS_M[k % len(OFFSETS_M)],
                                  control_rate_hz=CONTROL_RATE_HZ, dt_s=1.0 / CONTROL_RATE_HZ,
                                  rotor_time_constant_s=plan.rotor_time_constant_s)
        n = len(run.s)
        starts.append(sum(len(x) for x in xs))
        xs.append(run.result.x[:n])
        fs.append(run.result.rotor_applied_n[:n])
        k += 1
    states = np.concatenate(xs)[:n_states]
    forces = np.concatenate(fs)[:n_states] if lagged else None
    return StepCase(controller_name, plan, vehicle, controller, states, forces,
                    np.array(starts), ESTIMATE if controller.disturbance.enabled else None)


def time_steps(case: StepCase, reg: ManeuverRegulator) -> np.ndarray:
    """Seconds per :meth:`ManeuverRegulator.step` call over the case's states."""
    starts = set(case.starts.tolist())
    out = np.empty(len(case.states))
    clock = time.perf_counter
    states = list(case.states)
    forces = [None] * len(states) if case.rotor_forces_n is None else list(case.rotor_forces_n)
    est = case.disturbance
    step = reg.step
    for i, x in enumerate(states):
        if i in starts:
            reg.reset(x)
        t0 = clock()
        step(x, forces[i], est)
        out[i] = clock() - t0
    return out


def summary(seconds: np.ndarray) -> str:
    us = seconds * 1e6
    p50, p99, p999 = np.percentile(us, (50, 99, 99.9))
    return f"p50 {p50:6.1f} us  p99 {p99:6.1f} us  p99.9 {p999:7.1f} us  max {us.max():7.1f} us"


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--states", type=int, default=30_000)
    ap.add_argument("--repeat", type=int, default=1, help="time each case this many times")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()       # the first call in this process: compile or load the kernel
    seconds = time.perf_counter() - t0 if fastpath.warm_up() else None
    print("compiled step: " + ("unavailable (numba missing or MAVREG_PURE set)" if seconds is None else
                               f"compiled or loaded from numba's cache in {seconds:.2f} s"))
    for name in ("paper_lqr", "realistic"):
        case = closed_loop_states(name, args.states)
        for _ in range(args.repeat):
            for compiled in (False, True) if seconds is not None else (False,):
                reg = case.regulator(compiled=compiled)
                label = f"{name} {'compiled' if compiled else 'numpy'}"
                print(f"{label:20s} step over {len(case.states)} states: {summary(time_steps(case, reg))}")


if __name__ == "__main__":
    main()
