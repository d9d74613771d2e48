"""The SO(3) transverse dynamics and plant: defined through pitch +-90 deg, consistent with
the nominal, linearized exactly, and equal to the roll-pitch-yaw forms where those hold."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, maneuver_file
from mavreg.config.maneuver import load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.control.design.transverse import transverse_jacobians, transverse_rhs, transverse_rhs_so3
from mavreg.geometry.build import build_path
from mavreg.maneuver.flatness import flat_nominal
from mavreg.maneuver.plan import build_profiles
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.closed_loop import SimOptions, SimStatus, simulate

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
MODEL = QuadrotorModel.from_vehicle(VEHICLE)
MIXER = Mixer.from_vehicle(VEHICLE)

LOOP = """
kind: maneuver
version: 1
name: forward_loop
start: {position_m: [0.0, 0.0, -3.0], heading_deg: 0}
segments:
  - {name: run_up, line: {length_m: 18.0}}
  - {name: loop, arc: {radius_m: 2.0, angle_deg: 360, bend_deg: 0}, blend_m: 3.0}
  - {name: run_out, line: {length_m: 12.0}, blend_m: 3.0}
speed:
  initial_m_s: 0.5
  changes:
    - {segment: run_up, offset_m: 0.0, length_m: 10.0, to_m_s: 7.0}
    - {segment: loop, anchor: end, offset_m: 1.5, length_m: 10.0, to_m_s: 0.5}
yaw: {mode: velocity}
"""


@pytest.fixture(scope="module")
def loop_nominal():
    spec = load_maneuver_text(LOOP, "forward_loop.yaml")
    path = build_path(spec)
    speed, yaw = build_profiles(spec, path)
    s = np.linspace(0.5, path.length_m - 0.5, 3000)
    c, F, k, dk, ddk = path.evaluate(s)
    v4 = speed.evaluate(s)
    x, u, R = flat_nominal(MODEL, F, k, dk, ddk, c, v4, yaw.evaluate(s), "velocity")
    vdot, wdot = MODEL.body_derivatives(R[:, 2, :].T, x[:, 6:9].T, x[:, 9:12].T, u.T)
    dx = np.zeros_like(x)
    dx[:, 6:9], dx[:, 9:12] = vdot.T / v4[0][:, None], wdot.T / v4[0][:, None]
    return F, k, R, x, u, dx


def test_the_loop_passes_pitch_ninety(loop_nominal):
    x = loop_nominal[3]
    assert np.degrees(np.abs(x[:, 4]).max()) > 89.9


def test_so3_dynamics_vanish_on_the_nominal(loop_nominal):
    F, k, R, x, u, dx = loop_nominal
    out = transverse_rhs_so3(MODEL, F, k, R, x, u, dx, np.zeros((len(x), 11)), np.zeros((len(x), 4)))
    assert np.abs(out).max() < 1e-9


def test_linearization_through_pitch_ninety_matches_finite_differences(loop_nominal):
    F, k, R, x, u, dx = loop_nominal
    A, B = transverse_jacobians(MODEL, F, k, x, u, dx, Rbar=R)
    for i in np.argsort(-np.abs(x[:, 4]))[:4]:         # the points nearest pitch +-90 deg
        sl = slice(i, i + 1)
        args = (MODEL, F[sl], k[sl], R[sl], x[sl], u[sl], dx[sl])
        for j in range(11 + 4):
            d = np.zeros(15)
            d[j] = 1e-6
            plus = transverse_rhs_so3(*args, d[None, :11], d[None, 11:])
            minus = transverse_rhs_so3(*args, -d[None, :11], -d[None, 11:])
            fd = (plus - minus)[0] / 2e-6
            col = A[i, :, j] if j < 11 else B[i, :, j - 11]
            assert np.abs(fd - col).max() < 1e-6 * max(1.0, np.abs(A[i]).max())


def test_so3_and_rpy_linearizations_agree_at_level_attitude():
    """At roll = pitch = 0 the rotation vector and the roll-pitch-yaw differences have the
    same first-order kinematics, so A and B agree there."""
    xbar = np.zeros((1, 12))
    xbar[0, 6] = 5.0
    xbar[0, 5] = 0.3
    F = rpy_to_matrix(0.0, 0.0, 0.3)[None]
    k = np.zeros((1, 2))
    u = np.array([[VEHICLE.mass_kg * 9.81, 0, 0, 0]])
    dx = np.zeros((1, 12))
    A1, B1 = transverse_jacobians(MODEL, F, k, xbar, u, dx)
    A2, B2 = transverse_jacobians(MODEL, F, k, xbar, u, dx, Rbar=F)
    assert np.allclose(A1, A2, atol=1e-12) and np.allclose(B1, B2, atol=1e-12)
    w = np.zeros((1, 11))
    assert np.allclose(transverse_rhs(MODEL, F, k, xbar, u, dx, w, np.zeros((1, 4))),
                       transverse_rhs(MODEL, F, k, xbar, u, dx, w, np.zeros((1, 4)), Rbar=F))


def test_so3_plant_equals_the_rpy_plant_away_from_the_singularity():
    x0 = np.zeros(12)
    x0[9:12] = [0.3, 0.2, 0.1]
    x0[6] = 2.0

    def controller(t, x):
        return np.array([2.0, 2.1, 1.9, 2.05])

    runs = [simulate(MODEL, MIXER, controller, SimOptions(initial_state=x0, max_duration_s=2.0,
                                                         attitude=a)) for a in ("rpy", "so3")]
    d = runs[0].x - runs[1].x
    d[:, 3:6] = (d[:, 3:6] + np.pi) % (2 * np.pi) - np.pi      # the rpy plant does not wrap
    assert np.abs(d).max() < 1e-8


def test_so3_plant_turns_through_pitch_ninety():
    """A pure pitch rate (a principal axis, no torque) turns the body about y at that rate:
    the roll-pitch-yaw plant stops at the singularity, the SO(3) plant goes through."""
    x0 = np.zeros(12)
    x0[10] = 2.0

    def controller(t, x):
        return np.full(4, 1.0)

    rpy = simulate(MODEL, MIXER, controller, SimOptions(initial_state=x0, max_duration_s=1.5))
    assert rpy.status is SimStatus.DIVERGED and "singularity" in rpy.reason
    so3 = simulate(MODEL, MIXER, controller, SimOptions(initial_state=x0, max_duration_s=1.5,
                                                       attitude="so3"))
    assert so3.status is SimStatus.TIMEOUT
    for t, x in zip(so3.t[::100], so3.x[::100]):
        c, s = np.cos(2.0 * t), np.sin(2.0 * t)
        assert np.abs(rpy_to_matrix(*x[3:6]) - np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])).max() < 1e-9


def test_nominal_attitude_between_rows_matches_the_flat_map():
    """Plan.nominal_attitude between rows (the cubic in the rotation vector) against the flat
    map evaluated at those arc lengths, along a loop flown nose-first: within 1e-8 rad."""
    from mavreg.config.paths import DESIGN_CONTROLLER
    from mavreg.config.controller import load_controller
    from mavreg.config.maneuver import load_maneuver
    from mavreg.maneuver.plan import plan_spec
    from mavreg.model.so3 import attitude_error

    spec = load_maneuver(maneuver_file("forward_loop"))
    plan = plan_spec(spec, VEHICLE, load_controller(DESIGN_CONTROLLER))
    s = (plan.s[:-1] + plan.s[1:])[::37] / 2 + 0.13 * np.diff(plan.s)[::37]
    speed, yaw = build_profiles(spec, plan.path)
    c, F, k, dk, ddk = plan.path.evaluate(s)
    _, _, R = flat_nominal(MODEL, F, k, dk, ddk, c, speed.evaluate(s), yaw.evaluate(s), "velocity")
    err = np.linalg.norm(attitude_error(R, np.array([plan.nominal_attitude(q) for q in s])), axis=1)
    assert err.max() < 1e-8
    # the vectorized form (what a flight's truth is judged with) gives the same rotations
    many = plan.nominal_attitudes(s)
    assert np.linalg.norm(attitude_error(R, many), axis=1).max() < 1e-8
    np.testing.assert_allclose(many, [plan.nominal_attitude(q) for q in s], rtol=0, atol=1e-14)
    # clamped to the path's ends, as one at a time
    ends = np.array([-1.0, plan.length_m + 1.0])
    np.testing.assert_allclose(plan.nominal_attitudes(ends), [plan.nominal_attitude(q) for q in ends],
                               rtol=0, atol=1e-14)
