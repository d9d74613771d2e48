"""Maneuver regulation's point: a vehicle pushed back resumes where it is, without racing."""
from __future__ import annotations

import numpy as np

from mavreg.sim.maneuver_run import fly_on_design_model


def test_pushed_back_on_the_run_up_it_resumes_without_catching_up(barrel_roll_plan):
    plan = barrel_roll_plan
    # The run-up flies west: a 2 N force towards east for 1 s pushes the vehicle back.
    run = fly_on_design_model(plan, gust_force_n=(0.0, 2.0, 0.0), gust_window_s=(3.0, 4.0))
    assert run.metrics["completed"]
    n = len(run.s)
    t, x = run.result.t[:n], run.result.x[:n]
    speed = np.linalg.norm(x[:, 6:9], axis=1)
    nominal_speed = np.interp(run.s, plan.s, plan.speed_m_s)
    during = (t > 3.0) & (t < 4.5)
    after = t > 4.0
    assert (nominal_speed - speed)[during].max() > 0.3      # the gust really slowed it down
    # ...but afterwards it flies the speed the maneuver prescribes where it is (a timed
    # reference would have it race ahead to catch up), and it finishes late instead.
    assert (speed - nominal_speed)[after].max() < 0.1
    assert run.result.t[-1] > plan.duration_s + 1.0
    # The loop itself is flown as if nothing had happened.
    assert run.metrics["segments"]["loop"]["transverse_error_m"]["max"] < 1e-4
