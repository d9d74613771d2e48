"""The compiled regulator step against the reference numpy step, and its kernels against the
functions they stand for: the projection, the allocation, the disturbance compensation.

The kernels run compiled when numba is available and as plain Python under MAVREG_PURE=1;
either way they must give what the reference gives (to rounding). Timings are not tested.
"""
from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import pytest

from mavreg.accel import ACCELERATED
from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, controller_file, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.control.controllers.compensation_kernel import compensate, extra_force
from mavreg.control.estimation.disturbance import DisturbanceEstimate
from mavreg.control.estimation.lag_in_effect import RotorLagInEffect
from mavreg.control.estimation.disturbance import compensate as reference_compensate
from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.model.mixer_kernel import torques_first as torques_first_kernel
from mavreg.model.mixer_kernel import yaw_then_lift as yaw_then_lift_kernel
from mavreg.geometry.build import build_path
from mavreg.geometry.projection import Projector
from mavreg.geometry.projection_kernel import POINT_WIDTH, path_tables, project
from mavreg.planning.plan_io import plan_file
from mavreg.model.mixer import Mixer, torques_first, yaw_then_lift
from mavreg.model.rotation import rpy_to_matrix
from mavreg.model.rotation_kernel import log_vee
from mavreg.model.so3 import exp_so3, log_so3
from mavreg.sim.batch import BatchRun, fly_batch

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
BARREL = maneuver_file("barrel_roll")
ESTIMATE = DisturbanceEstimate((0.35, 0.12), (0.6, -0.4, 0.3), 0.97)
TORQUE_ESTIMATE = DisturbanceEstimate((0.35, 0.12), (0.6, -0.4, 0.3), 0.97,
                                      (0.01, -0.02, 0.005, 0.006, -0.004, 0.002))
LAG_ESTIMATE_S = 0.041
"""The rotors' time constant estimated in flight (the feedforward led by 41 ms, not the file's 20)."""
compiled_only = pytest.mark.skipif(not ACCELERATED, reason="numba missing or MAVREG_PURE set")

CIRCLE = """\
kind: maneuver
version: 1
name: circle
start: {position_m: [0, 0, -5], heading_deg: 0}
segments:
  - name: ring
    arc: {radius_m: 2.0, angle_deg: 360, bend_deg: 90}
speed: {initial_m_s: 3.0}
laps: {segment: ring, count: 2}
"""


def _projection_points(path, rng):
    """Tracking within 10 cm of the path, then out of the tube (near the circle's centre),
    back, a jump past the window, and points beyond both ends (the straight extensions)."""
    sigma = np.arange(-0.5, path.length_m + 0.5, 0.03)
    c, F = path.evaluate(sigma)[:2]
    a = rng.uniform(-0.1, 0.1, (len(sigma), 2))
    pts = c + a[:, :1] * F[:, :, 1] + a[:, 1:] * F[:, :, 2]
    beyond = [c[0] - 0.4 * F[0, :, 0], c[-1] + 0.7 * F[-1, :, 0] + 0.05 * F[-1, :, 1]]
    k = len(pts) // 3
    inside = c[k] + 1.9 * F[k, :, 1] * np.sign(path.point(sigma[k]).k[0] or 1.0)
    jump = path.evaluate(np.array([sigma[k] + 3.0]))[0][0]
    return np.concatenate([pts[:k], [inside, pts[k], jump], pts[k:], beyond])


@pytest.mark.parametrize("which", ["circle", "barrel_roll"])
def test_projection_kernel_gives_the_projectors_answers(which):
    spec = load_maneuver_text(CIRCLE, "circle.yaml") if which == "circle" else None
    path = build_path(spec) if spec is not None else plan_file(
        BARREL, VEHICLE, load_controller(PAPER_CONTROLLER)).path
    s_nodes, coef, ends = path_tables(path)
    proj = Projector(path)
    pts = _projection_points(path, np.random.default_rng(1))
    s_prev = proj.reset(pts[0], 0.0).s
    p = np.empty(POINT_WIDTH)
    outside = 0
    for y in pts:
        ref = proj.update(y)
        s, in_tube, dist = project(y[0], y[1], y[2], s_prev, proj.window_m, proj.tube_margin, s_nodes, coef, ends, p)
        s_prev = s
        assert s == pytest.approx(ref.s, abs=1e-9)
        assert in_tube == ref.in_tube
        assert dist == pytest.approx(ref.distance_m, abs=1e-9)
        np.testing.assert_allclose(p[:3], ref.point.position, atol=1e-12)
        np.testing.assert_allclose(p[3:12], ref.point.frame.reshape(9), atol=1e-12)
        np.testing.assert_allclose(p[12:14], ref.point.k, atol=1e-12)
        outside += not in_tube
    assert 0 < outside < 10          # the excursions were seen as such, the tracking was not


def test_allocation_kernels_are_the_mixers_allocations():
    Minv = Mixer.from_vehicle(VEHICLE).inverse
    rng = np.random.default_rng(2)
    # from inside the limits to beyond both ends, with torques up to the spread of the limit
    u = np.column_stack([rng.uniform(-5.0, 60.0, 4000), rng.uniform(-4.0, 4.0, 4000),
                         rng.uniform(-4.0, 4.0, 4000), rng.uniform(-0.4, 0.4, 4000)])
    flat = np.ascontiguousarray(Minv).reshape(16)
    f = np.empty(4)
    for F in (7.0, 12.0):
        for ui in u:
            yaw_then_lift_kernel(flat, ui, F, f)
            np.testing.assert_allclose(f, yaw_then_lift(Minv, ui, F), atol=1e-12)
            torques_first_kernel(flat, ui, F, f)
            np.testing.assert_allclose(f, torques_first(Minv, ui, F), atol=1e-12)


def test_rotation_vector_kernel_is_log_so3():
    rng = np.random.default_rng(4)
    axes = rng.normal(0, 1, (3000, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    # small (series), ordinary, and near pi (the axis from the symmetric part)
    angles = np.concatenate([rng.uniform(0, 2e-4, 1000), rng.uniform(0, 3.0, 1000),
                             rng.uniform(2.7, math.pi, 1000)])
    for v in axes * angles[:, None]:
        R = exp_so3(v)
        np.testing.assert_allclose(log_vee(tuple(R.reshape(9))), log_so3(R), atol=1e-12)


@pytest.mark.parametrize("max_turn_rad", [math.pi, 0.2617993877991494])
def test_compensation_kernel_is_compensate(max_turn_rad):
    rng = np.random.default_rng(3)
    base_drag = (0.1, 0.05)
    for k in range(500):
        xbar = np.concatenate([rng.normal(0, 1, 3), rng.uniform(-3.0, 3.0, 3) * (1, 0.45, 1),
                               rng.normal(0, 4, 3), rng.normal(0, 2, 3)])
        ahead = xbar + np.concatenate([np.zeros(3), rng.normal(0, 0.05, 9)])
        # the attitudes from the angles (the roll-pitch-yaw form), or given (the SO(3) form)
        R = rpy_to_matrix(*xbar[3:6]) if k % 2 else exp_so3(rng.normal(0, 1.5, 3))
        Ra = rpy_to_matrix(*ahead[3:6]) if k % 2 else R @ exp_so3(rng.normal(0, 0.05, 3))
        thrust, thrust_ahead = rng.uniform(2.0, 40.0), rng.uniform(2.0, 40.0)
        est = DisturbanceEstimate(tuple(rng.uniform(0.0, 1.5, 2)), tuple(rng.normal(0, 3, 3)), 1.0)
        ref_x, ref_t, ref_R = reference_compensate(
            xbar, R, thrust, est.extra_force_ned(R, R @ xbar[6:9], base_drag), Ra, thrust_ahead,
            est.extra_force_ned(Ra, Ra @ ahead[6:9], base_drag), 0.02, max_turn_rad)
        got = xbar.copy()
        Rt, Rat = tuple(R.reshape(9)), tuple(Ra.reshape(9))
        delta = (est.drag_n_s_per_m[0] - base_drag[0], est.drag_n_s_per_m[1] - base_drag[1], *est.force_ned_n)
        t, R2 = compensate(got, Rt, thrust, *extra_force(Rt, *(R @ xbar[6:9]), *delta), Rat, thrust_ahead,
                           *extra_force(Rat, *(Ra @ ahead[6:9]), *delta), 0.02, max_turn_rad)
        assert t == pytest.approx(ref_t, abs=1e-10)
        np.testing.assert_allclose(got, ref_x, atol=1e-9)
        np.testing.assert_allclose(np.reshape(R2, (3, 3)), ref_R, atol=1e-12)


def _held_back(x, rng):
    """States ``x`` (n, 12) of a flight with, in its second quarter, the body velocity scaled
    down as a gust would hold the vehicle back (to 40 %, then pushed backwards, then
    recovering): the speed governor's drops, push and recovery."""
    x = x.copy()
    n = len(x)
    scale = np.interp(np.arange(n), [n // 4, n // 4 + 20, n // 4 + 60, n // 4 + 80, n // 2],
                      [1.0, 0.4, -0.2, 0.6, 1.0])
    x[:, 6:9] *= scale[:, None]
    x[:, 6:9] += rng.normal(0.0, 0.02, (n, 3))
    return x


@pytest.fixture(scope="module")
def flight():
    """Plans of both controller files, each with either attitude error, and the states (and
    applied rotor forces) of two paper barrel rolls flown 0.6 m off, one with the rotors
    saturating at 8.5 N, every 10th control step (the warm start then jumps 8 cm, as at 100 Hz)
    and the last; then the first again, held back by a gust (:func:`_held_back`)."""
    plans = {}
    for name in ("paper_lqr", "realistic"):
        controller = load_controller(controller_file(name))
        for form in ("rpy", "so3"):
            plans[name, form] = (plan_file(BARREL, VEHICLE, dataclasses.replace(controller, attitude_error=form)),
                                 controller)
    runs = [BatchRun((0.6, 0.6, 0.6)), BatchRun((-0.6, 0.6, -0.6), saturation_n=8.5)]
    states, forces = [], []
    for r in fly_batch(plans["paper_lqr", "rpy"][0], runs):
        keep = np.r_[0:r.controller_calls:10, r.controller_calls - 1]
        states.append(r.x[keep])
        forces.append(r.rotor_applied_n[keep])
    states.append(_held_back(states[0], np.random.default_rng(5)))
    forces.append(forces[0])
    return plans, states, forces


def _regulator(plan, controller, compiled_flag, governed, limit_n, rotor_lag=None):
    """The regulator as the controller file builds it; ``governed``: its speed governor forced
    on; ``limit_n``: the allocation told the rotors give that much at most; ``rotor_lag``: the
    rotor lag in effect (None: the file's)."""
    gov = dataclasses.replace(controller.speed_governor, enabled=True) if governed else controller.speed_governor
    alloc = controller.allocation if limit_n is None else dataclasses.replace(controller.allocation,
                                                                             max_rotor_thrust_n=limit_n)
    return ManeuverRegulator(plan, VEHICLE, control_period_s=0.002,
                             max_compensation_turn_rad=controller.disturbance.max_compensation_turn_rad,
                             allocation=alloc, speed_governor=gov, compiled=compiled_flag, rotor_lag=rotor_lag)


@compiled_only
@pytest.mark.parametrize("name, form, governed, limit_n, disturbance, hand_over", [
    ("paper_lqr", "rpy", False, None, None, False), ("paper_lqr", "so3", False, None, None, False),
    ("paper_lqr", "rpy", True, 7.0, ESTIMATE, False),
    ("realistic", "rpy", False, None, None, False), ("realistic", "so3", False, None, None, True),
    ("realistic", "rpy", False, None, ESTIMATE, True), ("realistic", "so3", False, None, ESTIMATE, False),
    ("realistic", "so3", True, None, ESTIMATE, True), ("realistic", "so3", True, 7.0, None, False),
    ("realistic", "so3", True, 7.0, TORQUE_ESTIMATE, True)])
def test_compiled_step_gives_the_reference_steps_outputs(flight, name, form, governed, limit_n, disturbance,
                                                         hand_over):
    """Both steps give the same outputs; with the rotor-lag estimate (the last case) it moves
    from the file's 20 ms to 41 ms after the first step, and both leads follow it."""
    plans, states, forces = flight
    plan, controller = plans[name, form]
    estimate = SimpleNamespace(estimate_s=VEHICLE.rotor_time_constant_s, applied_s=VEHICLE.rotor_time_constant_s)
    lag = RotorLagInEffect.of_vehicle(VEHICLE, estimate if disturbance is TORQUE_ESTIMATE else None)
    ref, fast = (_regulator(plan, controller, flag, governed, limit_n, lag) for flag in (False, True))
    assert fast._compiled is not None and ref._compiled is None
    assert (ref.governor is not None) == (governed or controller.speed_governor.enabled)
    worst, retimed = 0.0, 0
    for xs, fs in zip(states, forces):
        ref.reset(xs[0])
        fast.reset(xs[0])
        for k, (x, f) in enumerate(zip(xs, fs)):
            if k == 1 and lag.estimate is not None:
                estimate.applied_s = LAG_ESTIMATE_S
            a = ref.step(x, f if hand_over else None, disturbance)
            b = fast.step(x, f if hand_over else None, disturbance)
            worst = max(worst, float(np.abs(a.rotor_forces_n - b.rotor_forces_n).max()))
            assert b.s == pytest.approx(a.s, abs=1e-9) and fast.s == b.s
            np.testing.assert_allclose(b.w, a.w, atol=1e-9)
            np.testing.assert_allclose(b.u, a.u, atol=1e-9)
            assert (b.in_tube, b.finished) == (a.in_tube, a.finished)
            assert b.speed_ref_m_s == pytest.approx(a.speed_ref_m_s, abs=1e-12)
            retimed += a.speed_ref_m_s < np.interp(a.s, plan.s, plan.speed_m_s) - 0.05
        assert b.finished              # the states reach the end of the maneuver
    assert worst < 1e-9
    assert (retimed > 100) == (ref.governor is not None)    # the governor acted where there is one


@compiled_only
def test_compiled_outputs_are_fresh_arrays(flight):
    plans, states, _ = flight
    reg = _regulator(*plans["paper_lqr", "rpy"], True, False, None)
    reg.reset(states[0][0])
    first = reg.step(states[0][0])
    kept = (first.w.copy(), first.u.copy(), first.rotor_forces_n.copy())
    reg.step(states[0][1])
    for a, b in zip((first.w, first.u, first.rotor_forces_n), kept):
        np.testing.assert_array_equal(a, b)
