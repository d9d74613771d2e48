"""Flatness nominal and transverse dynamics on the planned barrel roll."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mavreg.config.paths import maneuver_file
from mavreg.config.vehicle import G
from mavreg.control.design.transverse import transverse_jacobians, transverse_rhs
from mavreg.config.maneuver import load_maneuver
from mavreg.maneuver.flatness import nominal_from_flat
from mavreg.maneuver import plan as plan_mod
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import wrap_angle


@pytest.fixture(scope="module")
def plan(barrel_roll_plan):
    return barrel_roll_plan


@pytest.fixture(scope="module")
def model(plan):
    return QuadrotorModel.from_vehicle(plan.vehicle)


def _away_from_blend_ends(plan, s, margin=0.05):
    edges = np.array([sp.s_start_m for sp in plan.path.spans] + [plan.length_m])
    return s[np.min(np.abs(s[:, None] - edges[None, :]), axis=1) > margin]


@pytest.fixture(scope="module")
def exact(plan, model):
    """x-bar(s), u-bar(s) straight from the flatness map at any s (not the table)."""
    spec = load_maneuver(maneuver_file("barrel_roll"))
    speed, yaw = plan_mod.build_profiles(spec, plan.path)

    def at(s):
        s = np.atleast_1d(np.asarray(s, dtype=float))
        c, F, k, dk, ddk = plan.path.evaluate(s)
        v4 = speed.evaluate(s)
        x, u = nominal_from_flat(model, F, k, dk, ddk, c, v4, yaw.evaluate(s))
        return x, u, v4[0]
    return at


def test_nominal_satisfies_the_model(plan, model, exact):
    """x-bar'(s) = f(x-bar, u-bar)/v, x-bar' by central differences of the flat nominal."""
    rng = np.random.default_rng(1)
    s = _away_from_blend_ends(plan, rng.uniform(0.5, plan.length_m - 0.5, 40))
    h = 1e-4
    for si in s:
        x, u, v = exact([si - h, si, si + h])
        d = (x[2] - x[0]) / (2 * h)
        want = model.f(x[1], u[1]) / v[1]
        # rtol 1e-4, not 1e-6: the path tabulates dk by Hermite and ddk linearly between nodes, so
        # d(dk)/ds and ddk differ at O(spacing^2); the body-rate rows see ~1e-5 relative.
        np.testing.assert_allclose(d, want, rtol=1e-4, atol=1e-5 * (1 + np.abs(want).max()))
    # and the plan's table agrees with the flat nominal between its nodes
    for si in s[:10]:
        x, _, _ = exact(si)
        diff = plan.nominal_state(si) - x[0]
        diff[3:6] = wrap_angle(diff[3:6])       # the table's angles are unwrapped
        np.testing.assert_allclose(diff, 0.0, atol=1e-6)


def test_table_derivative_is_model_over_speed(plan, model):
    np.testing.assert_allclose(plan.dx, model.f(plan.x.T, plan.u.T).T / plan.speed_m_s[:, None],
                               rtol=1e-12, atol=1e-12)


def test_flatness_round_trip_open_loop(plan, model, exact):
    """Integrating the design model with u-bar(s(t)) from x-bar(0) stays on x-bar(s(t))."""
    # start just before the loop: the blend and the circle, attitude and rates changing
    span = next(sp for sp in plan.path.spans if sp.name == "loop")
    s0 = span.s_start_m - 1.0

    def rhs(t, z):
        x, u, v = exact(z[12])
        return np.concatenate([model.f(z[:12], u[0]), v])

    z0 = np.concatenate([exact(s0)[0][0], [s0]])
    sol = solve_ivp(rhs, (0.0, 0.5), z0, rtol=1e-10, atol=1e-12, max_step=2e-3,
                    dense_output=True)
    assert sol.success
    for t in np.linspace(0.05, 0.5, 10):
        z = sol.sol(t)
        err = z[:12] - exact(z[12])[0][0]
        assert np.max(np.abs(err)) < 1e-5, (t, err)
    assert sol.y[12, -1] - s0 > 3.5   # it flew well into the circle at ~8 m/s


def _nominal_at(plan, idx):
    s = plan.s[idx]
    c, F, k, dk, ddk = plan.path.evaluate(s)
    return F, k, plan.x[idx], plan.u[idx], plan.dx[idx]


def test_transverse_rhs_vanishes_on_the_nominal(plan, model):
    idx = np.linspace(0, len(plan.s) - 1, 200).astype(int)
    F, k, x, u, dx = _nominal_at(plan, idx)
    n = len(idx)
    out = transverse_rhs(model, F, k, x, u, dx, np.zeros((n, 11)), np.zeros((n, 4)))
    assert np.max(np.abs(out)) < 1e-8


def test_jacobians_match_central_differences(plan, model):
    idx = np.linspace(10, len(plan.s) - 10, 7).astype(int)
    F, k, x, u, dx = _nominal_at(plan, idx)
    A, B = transverse_jacobians(model, F, k, x, u, dx)
    n = len(idx)
    h = 1e-6
    for j in range(11):
        dw = np.zeros((n, 11))
        dw[:, j] = h
        fd = (transverse_rhs(model, F, k, x, u, dx, dw, np.zeros((n, 4)))
              - transverse_rhs(model, F, k, x, u, dx, -dw, np.zeros((n, 4)))) / (2 * h)
        np.testing.assert_allclose(A[:, :, j], fd, rtol=1e-6, atol=1e-6 * np.abs(A).max())
    for j in range(4):
        du = np.zeros((n, 4))
        du[:, j] = h
        fd = (transverse_rhs(model, F, k, x, u, dx, np.zeros((n, 11)), du)
              - transverse_rhs(model, F, k, x, u, dx, np.zeros((n, 11)), -du)) / (2 * h)
        np.testing.assert_allclose(B[:, :, j], fd, rtol=1e-6, atol=1e-6 * np.abs(B).max())


def test_barrel_roll_thrust_figures(plan):
    m, v, r = plan.vehicle.mass_kg, 8.0, 1.5
    th = plan.summary()["thrust_n"]
    assert th["max"] == pytest.approx(m * (G + v * v / r), abs=0.2)          # ~39.3 N
    assert th["at_highest_point"] == pytest.approx(m * (v * v / r - G), abs=0.2)  # ~24.6 N


def test_barrel_roll_attitude(plan):
    loop = next(sp for sp in plan.path.spans if sp.name == "loop")
    roll, pitch, yaw = plan.x[:, 3], plan.x[:, 4], plan.x[:, 5]
    assert abs(roll[0]) < 1e-6
    assert np.degrees(roll[-1]) == pytest.approx(360.0, abs=1.0)
    # (the loop is 400 deg: the roll overshoots 360 in the 40 deg climb-out, then settles)
    assert np.degrees(roll).max() < 430.0
    assert np.degrees(np.max(np.abs(pitch))) < 1.0
    assert np.degrees(np.max(np.abs(yaw))) < 1.0
    # through the loop the roll passes 90, 180 and 270 degrees
    in_loop = (plan.s >= loop.s_start_m) & (plan.s <= loop.s_end_m)
    assert np.degrees(roll[in_loop]).min() < 90 and np.degrees(roll[in_loop]).max() > 270
