"""Drag in the design model: the flat nominal feeds it forward and stays a solution."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.vehicle import load_vehicle
from mavreg.maneuver import plan as plan_mod
from mavreg.maneuver.flatness import nominal_from_flat
from mavreg.planning.plan_io import plan_file
from mavreg.model.quadrotor import QuadrotorModel

BASE = load_vehicle(DEFAULT_VEHICLE)
DRAG = dataclasses.replace(BASE, rotor_drag_n_s_per_m=(0.34, 0.12), parasitic_drag_n_s2_per_m2=0.01)


@pytest.fixture(scope="module")
def flat():
    spec = load_maneuver(maneuver_file("barrel_roll"))
    plan = plan_file(maneuver_file("barrel_roll"), BASE,
                     load_controller(PAPER_CONTROLLER), strict=False)
    speed, yaw = plan_mod.build_profiles(spec, plan.path)

    def at(model, s):
        s = np.atleast_1d(np.asarray(s, dtype=float))
        c, F, k, dk, ddk = plan.path.evaluate(s)
        v4 = speed.evaluate(s)
        x, u = nominal_from_flat(model, F, k, dk, ddk, c, v4, yaw.evaluate(s))
        return x, u, v4[0]
    return plan, at


def test_drag_model_force_is_the_body_drag():
    """f(x, u) with drag minus without is -(C v_b + c_p |v| v_b)/m in the body frame."""
    m0, m1 = QuadrotorModel.from_vehicle(BASE), QuadrotorModel.from_vehicle(DRAG)
    x = np.array([0, 0, -3, 0.3, -0.2, 1.0, 4.0, -1.0, 0.5, 0.1, 0.2, -0.3])
    u = np.array([8.0, 0.01, -0.02, 0.003])
    d = m1.f(x, u) - m0.f(x, u)
    vb = x[6:9]
    want = -(np.array([0.34, 0.34, 0.12]) * vb + 0.01 * np.linalg.norm(vb) * vb) / BASE.mass_kg
    np.testing.assert_allclose(d[6:9], want, rtol=1e-12)
    np.testing.assert_allclose(np.delete(d, [6, 7, 8]), 0.0, atol=1e-15)


def test_nominal_with_drag_satisfies_the_model_with_drag(flat):
    plan, at = flat
    model = QuadrotorModel.from_vehicle(DRAG)
    rng = np.random.default_rng(3)
    edges = np.array([sp.s_start_m for sp in plan.path.spans] + [plan.length_m])
    s = rng.uniform(0.5, plan.length_m - 0.5, 40)
    s = s[np.min(np.abs(s[:, None] - edges[None, :]), axis=1) > 0.05]
    h = 1e-4
    for si in s:
        x, u, v = at(model, [si - h, si, si + h])
        d = (x[2] - x[0]) / (2 * h)
        want = model.f(x[1], u[1]) / v[1]
        np.testing.assert_allclose(d, want, rtol=1e-4, atol=1e-5 * (1 + np.abs(want).max()))


def test_drag_costs_thrust_along_the_velocity(flat):
    """At the loop's bottom (8 m/s, velocity across the thrust axis) the drag is fed forward as
    a tilt into the wind: the thrust grows by about (c_xy v + c_p v^2)^2 / (2 f), and the
    attitude leans back against the motion."""
    plan, at = flat
    s = np.array([20.5])
    x0, u0, v = at(QuadrotorModel.from_vehicle(BASE), s)
    x1, u1, _ = at(QuadrotorModel.from_vehicle(DRAG), s)
    assert u1[0, 0] > u0[0, 0]
    assert np.abs(x1[0, 3:6] - x0[0, 3:6]).max() > np.radians(2.0)
