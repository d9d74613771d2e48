"""Time-indexed trackers: the timed nominal, the TVLQR and the SE(3) tracker on the design model."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.control.design.riccati import sweep_backward
from mavreg.planning.plan_io import plan_file
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.closed_loop import SimOptions, simulate
from mavreg.trackers.se3 import Se3Gains, Se3Tracker
from mavreg.trackers.timed import TimedNominal
from mavreg.trackers.tvlqr import TimeVaryingLqr, TvlqrWeights, full_state_jacobians

CONTROLLER = load_controller(PAPER_CONTROLLER)


@pytest.fixture(scope="module")
def timed():
    plan = plan_file(maneuver_file("barrel_roll"), load_vehicle(DEFAULT_VEHICLE), CONTROLLER)
    return TimedNominal(plan)


@pytest.fixture(scope="module")
def tvlqr(timed):
    return TimeVaryingLqr(timed, TvlqrWeights.from_controller(CONTROLLER), lead_s=0.0005)


def test_the_clock_runs_at_the_profiles_speed_and_the_reference_obeys_the_model(timed):
    plan = timed.plan
    assert timed.duration_s == pytest.approx(plan.duration_s, abs=1e-5)
    assert timed.s_at(timed.duration_s) == pytest.approx(plan.length_m, abs=1e-9)
    h = 1e-5
    for t in (0.3, 3.65, 6.31, 7.37, 7.9, 12.0, 21.0):
        s = timed.s_at(t)
        assert (timed.s_at(t + h) - timed.s_at(t - h)) / (2 * h) == pytest.approx(timed.speed_at(s), rel=1e-6)
        # d/dt x(t) = f(x(t), u(t)): the timed nominal is a trajectory of the design model
        ref = timed.reference(t)
        dx = (timed.reference(t + h).x - timed.reference(t - h).x) / (2 * h)
        np.testing.assert_allclose(dx, timed.model.f(ref.x, ref.u), atol=2e-4 * max(1.0, np.abs(dx).max()))
        # the acceleration is the position's second derivative
        dd = (timed.reference(t + h).x[:3] - 2 * ref.x[:3] + timed.reference(t - h).x[:3]) / h ** 2
        np.testing.assert_allclose(ref.acceleration_ned_m_s2, dd, atol=1e-3 * max(1.0, np.abs(dd).max()))
    assert timed.t_of_s(11.0) == pytest.approx(6.3112, abs=1e-3)
    # past the end it flies on along the run-out at its last speed, on the path's extension
    x_end, x_on = timed.state_at_s(plan.length_m), timed.reference(timed.duration_s + 2.0).x
    v = rpy_to_matrix(*x_end[3:6]) @ x_end[6:9]
    np.testing.assert_allclose(x_on[:3], x_end[:3] + 2.0 * v, atol=1e-6)


def test_the_clocks_scalar_speed_is_the_splines_to_the_bit(timed):
    """The clock integrates v(s) in plain floats (``_speed_scalar``); it must be the cubic
    spline's own number everywhere, knots, ends and beyond them included, so that the clock
    (and a campaign's time allowed) is what the spline gives."""
    plan = timed.plan
    s = np.r_[np.random.default_rng(1).uniform(-2.0, plan.length_m + 2.0, 20000), plan.s]
    ours = np.array([timed._speed_scalar(float(q)) for q in s])
    np.testing.assert_array_equal(ours, timed.speed_at(s))
    # the order of the sum matters at the last bit: Horner's form of the same cubic is not it
    sc = np.clip(s, plan.s[0], plan.s[-1])
    i = np.clip(np.searchsorted(timed._speed.x, sc, side="right") - 1, 0, timed._speed.c.shape[1] - 1)
    c, d = timed._speed.c[:, i], sc - timed._speed.x[i]
    horner = ((c[0] * d + c[1]) * d + c[2]) * d + c[3]
    np.testing.assert_allclose(horner, ours, rtol=1e-12)
    assert not np.array_equal(horner, ours)


def _fly(timed, tracker, t0: float, duration_s: float, x0=None):
    """Fly ``tracker`` on the design model from the reference's state at ``t0`` (or x0)."""
    v = timed.plan.vehicle
    x0 = timed.reference(t0).x if x0 is None else x0
    opts = SimOptions(initial_state=tuple(x0), dt_s=0.001, max_duration_s=duration_s)
    res = simulate(QuadrotorModel.from_vehicle(v), Mixer.from_vehicle(v),
                   lambda t, x: tracker.step(t0 + t, x).rotor_forces_n, opts)
    ref = np.array([timed.reference(t0 + t).x for t in res.t])
    pos = np.linalg.norm(res.x[:, :3] - ref[:, :3], axis=1)
    R = rpy_to_matrix(*res.x[:, 3:6].T).transpose(2, 0, 1)
    Rn = rpy_to_matrix(*ref[:, 3:6].T).transpose(2, 0, 1)
    att = np.degrees(np.arccos(np.clip((np.einsum("kij,kij->k", R, Rn) - 1) / 2, -1, 1)))
    return res, pos, att


@pytest.mark.parametrize("which", ["tvlqr", "se3"])
def test_each_tracker_flies_the_loop_from_its_exact_initial_state(timed, tvlqr, which):
    tracker = tvlqr if which == "tvlqr" else Se3Tracker(timed, lead_s=0.0005)
    t0 = timed.t_of_s(14.0)
    res, pos, att = _fly(timed, tracker, t0, 2.4)            # the blend, the loop, 8 m/s, 4.4 g
    assert res.status.value == "timeout" and timed.s_at(t0 + res.t[-1]) > 29.0
    assert pos.max() < 2e-5 and att.max() < 2e-3


def test_the_tvlqr_riccati_with_constant_coefficients_is_the_algebraic_one():
    model = QuadrotorModel.from_vehicle(load_vehicle(DEFAULT_VEHICLE))
    x = np.zeros(12)
    x[6] = 3.0                                 # level flight north at 3 m/s
    A, B = full_state_jacobians(model, [x], [model.hover_input()])
    w = TvlqrWeights.from_controller(CONTROLLER)
    Q, R = np.diag(w.q), np.diag(w.r)
    n = 8001                                   # 8 s backward from P = 0, 1 ms steps
    P, K = sweep_backward(np.repeat(A, n, 0), np.repeat(B, n, 0), np.repeat(A, n - 1, 0),
                          np.repeat(B, n - 1, 0), 0.001, Q, R, np.zeros((12, 12)))
    P_are = scipy.linalg.solve_continuous_are(A[0], B[0], Q, R)
    np.testing.assert_allclose(P[0], P_are, rtol=1e-7, atol=1e-9 * np.abs(P_are).max())
    np.testing.assert_allclose(K[0], np.linalg.solve(R, B[0].T @ P_are), rtol=1e-7, atol=1e-8)
    # it got there by sweeping: 0.1 s before the end it is still far from it
    assert np.abs(P[-1]).max() == 0.0 and np.abs(P[-101] - P_are).max() > 1e-3 * np.abs(P_are).max()


def test_the_tvlqr_takes_the_regulators_weights_on_every_position_axis():
    w = TvlqrWeights.from_controller(CONTROLLER)
    assert w.q == (100.0, 100.0, 100.0, 9.0, 9.0, 9.0, 10.0, 10.0, 10.0, 3.0, 3.0, 3.0)
    assert w.r == (0.1, 0.1, 1.0, 0.1)
    with pytest.raises(ValueError):
        TvlqrWeights(q=(1.0,) * 11, r=(1.0,) * 4)


def test_se3_asks_for_the_nominal_input_on_the_nominal(timed):
    se3 = Se3Tracker(timed)
    for t in (1.0, 6.31, 7.5, 8.0, 12.0):
        ref = timed.reference(t)
        np.testing.assert_allclose(se3.step(t, ref.x).u, ref.u, atol=1e-9 * max(1.0, np.abs(ref.u).max()))


def test_se3_desired_rotation_is_a_rotation_with_the_force_along_minus_b3(timed):
    se3 = Se3Tracker(timed)
    F = np.array([1.0, -2.0, -9.0])
    for b1 in (np.array([1.0, 0.0, 0.0]), -F / np.linalg.norm(F)):     # the second: along b3 (fallback)
        Rd = se3.desired_rotation(F, b1, np.array([0.0, 1.0, 0.0]))
        np.testing.assert_allclose(Rd.T @ Rd, np.eye(3), atol=1e-12)
        assert np.linalg.det(Rd) == pytest.approx(1.0)
        np.testing.assert_allclose(Rd[:, 2], -F / np.linalg.norm(F), atol=1e-12)


def test_se3_gains_leave_the_cascade_stable_where_the_papers_attitude_gains_do_not(timed):
    """Hovering on the run-out's extension, 30 cm off to the north: with the chosen gains the
    error dies out; with the paper's attitude gains (10.4 rad/s, damping 1.5) and the nominal's
    body rates as the attitude feedforward it does not (no phase margin)."""
    t0 = timed.duration_s + 1.0
    x0 = timed.reference(t0).x
    x0[0] += 0.3
    _, pos, _ = _fly(timed, Se3Tracker(timed), t0, 3.0, x0)
    assert pos[-500:].max() < 0.01 and pos[-1] < 3e-3
    lee = Se3Gains(attitude_rad_s=np.sqrt(8.81 / 0.0820), attitude_damping=2.54 / (2 * np.sqrt(8.81 * 0.0820)))
    _, pos_lee, _ = _fly(timed, Se3Tracker(timed, lee), t0, 3.0, x0)
    assert pos_lee[-500:].max() > 0.1
