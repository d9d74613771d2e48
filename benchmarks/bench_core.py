"""Time to plan the barrel roll (nominal, linearization, gains) and the controller step.

Run: ``python benchmarks/bench_core.py``. Prints figures; asserts nothing (shared machines
are noisy). The step is timed on a real closed-loop trajectory of the design model.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.vehicle import load_vehicle
from mavreg.control.regulator import ManeuverRegulator
from mavreg.control.riccati import care, sweep_backward
from mavreg.control.transverse import transverse_jacobians
from mavreg.geometry.build import build_path
from mavreg.maneuver import plan as planmod
from mavreg.model.quadrotor import QuadrotorModel

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    vehicle = load_vehicle(ROOT / "params/vehicles/mk_quadro.yaml")
    controller = load_controller(ROOT / "params/controller/paper_lqr.yaml")
    spec = load_maneuver(ROOT / "params/maneuvers/barrel_roll.yaml")
    model = QuadrotorModel.from_vehicle(vehicle)
    t0 = time.perf_counter()
    path = build_path(spec)
    speed, yaw = planmod.build_profiles(spec, path)
    s = planmod._time_grid(path, speed, controller.riccati_step_s)
    t1 = time.perf_counter()
    F, k, x, u, dx, v = planmod._nominal(model, path, speed, yaw, s)
    sm = (s[:-1] + s[1:]) / 2
    Fm, km, xm, um, dxm, _ = planmod._nominal(model, path, speed, yaw, sm)
    t2 = time.perf_counter()
    A, B = transverse_jacobians(model, F, k, x, u, dx)
    Am, Bm = transverse_jacobians(model, Fm, km, xm, um, dxm)
    t3 = time.perf_counter()
    Q, R = np.diag(controller.q), np.diag(controller.r)
    P_T, _ = care(A[-1], B[-1], Q, R)
    sweep_backward(A, B, Am, Bm, np.diff(s), Q, R, P_T, step_check="off")
    t4 = time.perf_counter()
    print(f"plan barrel_roll ({len(s)} nodes):")
    print(f"  path + grid      {1e3 * (t1 - t0):8.1f} ms")
    print(f"  nominal          {1e3 * (t2 - t1):8.1f} ms")
    print(f"  linearization    {1e3 * (t3 - t2):8.1f} ms")
    print(f"  gain schedule    {1e3 * (t4 - t3):8.1f} ms")
    t5 = time.perf_counter()
    plan = planmod.plan_spec(spec, vehicle, controller)
    print(f"  plan_spec total  {1e3 * (time.perf_counter() - t5):8.1f} ms (with checks)")

    reg = ManeuverRegulator(plan, vehicle)
    states = [plan.nominal_state(si) + np.r_[0.01, -0.01, 0.01, np.zeros(9)]
              for si in np.linspace(0, plan.length_m, 4000)]
    reg.reset(states[0])
    times = np.empty(len(states))
    for i, xs in enumerate(states):
        a = time.perf_counter()
        reg.step(xs)
        times[i] = time.perf_counter() - a
    us = times * 1e6
    print(f"controller step over {len(us)} states along the path: median {np.median(us):.1f} us, "
          f"p99 {np.percentile(us, 99):.1f} us, max {us.max():.1f} us (1 kHz budget: 1000 us)")


if __name__ == "__main__":
    main()
