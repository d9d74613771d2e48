"""The s-scheduled LQR: steady gain on a straight line, and closed-loop barrel rolls."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.control.design.transverse import transverse_jacobians
from mavreg.planning.plan_io import plan_file, plan_text
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.sim.maneuver_run import fly_on_design_model

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
CONTROLLER = load_controller(PAPER_CONTROLLER)

LINE = """\
kind: maneuver
version: 1
name: line
start: {position_m: [0, 0, -3], heading_deg: 45}
segments:
  - name: straight
    line: {length_m: 30.0}
speed: {initial_m_s: 3.0}
"""


def test_mid_line_gain_is_the_steady_lqr_gain():
    plan = plan_text(LINE, "line.yaml", VEHICLE, CONTROLLER)
    i = len(plan.s) // 2
    model = QuadrotorModel.from_vehicle(VEHICLE)
    c, F, k, dk, ddk = plan.path.evaluate(plan.s[i:i + 1])
    A, B = transverse_jacobians(model, F, k, plan.x[i:i + 1], plan.u[i:i + 1], plan.dx[i:i + 1])
    Q, R = np.diag(CONTROLLER.q), np.diag(CONTROLLER.r)
    P = solve_continuous_are(A[0], B[0], Q, R)
    K = np.linalg.solve(R, B[0].T @ P)
    np.testing.assert_allclose(plan.K[i], K, rtol=1e-5, atol=1e-6 * np.abs(K).max())
    # hover-like nominal: level, thrust m g
    assert plan.u[i, 0] == pytest.approx(VEHICLE.mass_kg * 9.81, rel=1e-9)


@pytest.fixture(scope="module")
def plan(barrel_roll_plan):
    return barrel_roll_plan


def _span(plan, name):
    return next((a, b) for n, a, b in plan.segments if n == name)


def test_nominal_start_tracks_to_under_a_millimetre(plan):
    m = fly_on_design_model(plan).metrics
    assert m["stable"] and m["completed"]
    assert m["transverse_error_m"]["max"] < 1e-3


def test_offset_start_converges_before_the_loop(plan):
    run = fly_on_design_model(plan, offset_m=(0.6, 0.6, 0.6))
    m = run.metrics
    assert m["stable"] and m["completed"]
    _, run_up_end = _span(plan, "run_up")
    sel = (run.s >= run_up_end - 2.0) & (run.s <= run_up_end)
    assert sel.sum() > 100
    assert np.max(np.hypot(run.w[sel, 0], run.w[sel, 1])) < 0.01
    loop = m["segments"]["loop"]
    assert loop["transverse_error_m"]["max"] < 0.01
    assert loop["attitude_error_deg"]["max"] < 0.5


def test_robust_to_ten_percent_inertia_error(plan):
    J = tuple(1.1 * j for j in VEHICLE.inertia_kg_m2)
    m = fly_on_design_model(plan, inertia_kg_m2=J).metrics
    assert m["stable"] and m["completed"]
    assert m["segments"]["loop"]["transverse_error_m"]["max"] < 0.02


@pytest.mark.slow
def test_three_laps_with_rotor_noise_and_saturation():
    """Issue 2: stable over 3 laps with 0.1 N rotor noise, saturation none / 8.5 / 7 N."""
    plan3 = plan_file(maneuver_file("barrel_roll"), VEHICLE, CONTROLLER, laps=3)
    assert plan3.laps == 3
    for saturation in (None, 8.5, 7.0):
        m = fly_on_design_model(plan3, rotor_noise_sd_n=0.1, saturation_n=saturation,
                                seed=1).metrics
        assert m["stable"] and m["completed"], saturation
