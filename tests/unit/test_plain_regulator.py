"""The controller-step benchmark's baseline (scipy interpolators, small numpy arrays) computes
what the production regulator computes, state by state along a closed-loop barrel roll."""
from __future__ import annotations

import numpy as np

from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.sim.batch import BatchRun, fly_batch
from harness.plain_regulator import PlainRegulator


def test_plain_step_agrees_with_the_regulator_on_closed_loop_states(vehicle, barrel_roll_plan):
    """The first 9 s of a flight from 0.6 m off (the offset taken out, the run-up, the
    loop's first quarter at 8 m/s), each state pushed about 5 cm and 3 deg further off; both steps are
    taken on every state in turn."""
    plan = barrel_roll_plan
    run = fly_batch(plan, [BatchRun((0.6, 0.6, 0.6))], extra_time_s=9.0 - plan.duration_s)[0]
    rng = np.random.default_rng(1)
    states = run.x + np.concatenate([rng.normal(0, 0.05, (len(run.x), 3)), rng.normal(0, 0.05, (len(run.x), 3)),
                                     np.zeros((len(run.x), 6))], axis=1)
    prod = ManeuverRegulator(plan, vehicle, control_period_s=1e-3)
    plain = PlainRegulator(plan, vehicle, control_period_s=1e-3)
    prod.reset(states[0])
    plain.reset(states[0])
    assert plain.s == prod.s
    worst = 0.0
    for x in states:
        ref = prod.step(x)
        worst = max(worst, float(np.abs(plain.step(x) - ref.rotor_forces_n).max()))
        assert abs(plain.s - ref.s) < 1e-9
    assert worst < 1e-9
    assert plain.s > 20.0           # in the loop (18 m to 28.5 m)
