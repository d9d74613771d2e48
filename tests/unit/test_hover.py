"""Hover LQR and C^2 ramps on the design model (RK4, no sockets, no wall clock)."""

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.config.vehicle import load_vehicle
from mavreg.control.controllers.hover import HoverController, HoverParams, hold_ramp, plan_ramp
from mavreg.model.quadrotor import QuadrotorModel

VEHICLE = load_vehicle(DEFAULT_VEHICLE)


def _simulate(ctrl, ramp, x0, duration_s, dt_s=0.002):
    model = QuadrotorModel.from_vehicle(VEHICLE)
    x = np.array(x0, dtype=float)
    peak = 0.0
    errs = []
    for k in range(int(round(duration_s / dt_s))):
        out = ctrl.step(x, ramp, k * dt_s)
        forces = np.clip(out.rotor_forces_n, 0.0, VEHICLE.max_rotor_thrust_n)
        peak = max(peak, float(np.max(np.abs(out.rotor_forces_n))))
        u = ctrl.mixer.to_wrench(forces)
        f = lambda xx: model.f(xx, u)  # noqa: E731
        k1 = f(x); k2 = f(x + dt_s / 2 * k1); k3 = f(x + dt_s / 2 * k2); k4 = f(x + dt_s * k3)
        x = x + dt_s / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        p_ref = ramp.sample(k * dt_s)[0]
        errs.append(np.linalg.norm(x[:3] - p_ref))
    return x, peak, np.array(errs)


def test_gain_stabilizes_linearization():
    ctrl = HoverController(VEHICLE)
    for yaw in (0.0, 1.0, -2.5):
        K = ctrl.gain(yaw)
        assert K.shape == (4, 12) and np.all(np.isfinite(K))


def test_hold_recovers_offset_without_saturation():
    ctrl = HoverController(VEHICLE)
    x0 = np.zeros(12)
    x0[:3] = [0.3, -0.3, -2.2]
    x, peak, _ = _simulate(ctrl, hold_ramp([0.0, 0.0, -2.0], 0.0), x0, 6.0)
    assert np.linalg.norm(x[:3] - [0.0, 0.0, -2.0]) < 0.01
    assert peak < VEHICLE.max_rotor_thrust_n


def test_yaw_error_is_wrapped():
    ctrl = HoverController(VEHICLE)
    x = np.zeros(12)
    x[5] = np.pi - 0.05
    out = ctrl.step(x, hold_ramp([0, 0, 0], -np.pi + 0.05), 0.0)
    assert abs(out.error[5] + 0.1) < 1e-9


def test_ramp_is_c2_and_respects_limits():
    params = HoverParams()
    ramp = plan_ramp([0, 0, 0], [0, 0, 0], 0.0, [2.0, 1.0, -3.0], [0.4, 0.0, 0.0], 0.5, params)
    ts = np.linspace(-0.1, ramp.duration_s + 0.5, 2000)
    samples = [ramp.sample(t) for t in ts]
    pos = np.array([s[0] for s in samples]); vel = np.array([s[1] for s in samples])
    acc = np.array([s[2] for s in samples])
    assert np.allclose(pos[0], 0) and np.allclose(ramp.sample(ramp.duration_s)[0], [2.0, 1.0, -3.0])
    assert np.max(np.linalg.norm(acc, axis=1)) <= params.max_accel_m_s2 + 1e-9
    assert np.max(np.linalg.norm(vel, axis=1)) <= params.max_speed_m_s * 1.001
    # continuity of velocity and acceleration across both ends (C^2)
    d = np.diff(acc, axis=0)
    assert np.max(np.abs(d)) < 0.05
    np.testing.assert_allclose(ramp.sample(ramp.duration_s - 1e-9)[1], [0.4, 0, 0], atol=1e-6)


def test_takeoff_ramp_tracks_closely_and_never_saturates():
    ctrl = HoverController(VEHICLE)
    ramp = plan_ramp([0, 0, 0], [0, 0, 0], 0.0, [0, 0, -3.0], [0, 0, 0], 0.0, ctrl.params)
    x, peak, errs = _simulate(ctrl, ramp, np.zeros(12), ramp.duration_s + 2.0)
    assert errs.max() < 0.05
    assert peak < 0.5 * VEHICLE.max_rotor_thrust_n
    assert abs(x[2] + 3.0) < 0.005


@pytest.mark.parametrize("yaw", [0.0, 1.2])
def test_moving_end_ramp_reaches_velocity(yaw):
    ctrl = HoverController(VEHICLE)
    x0 = np.zeros(12); x0[2] = -3.0; x0[5] = yaw
    v1 = 0.4 * np.array([np.cos(yaw), np.sin(yaw), 0.0])
    ramp = plan_ramp([0, 0, -3.0], [0, 0, 0], yaw, [np.cos(yaw), np.sin(yaw), -3.0], v1, yaw, ctrl.params)
    x, peak, errs = _simulate(ctrl, ramp, x0, ramp.duration_s)
    assert errs.max() < 0.03
    from mavreg.model.rotation import rpy_to_matrix
    v_ned = rpy_to_matrix(*x[3:6]) @ x[6:9]
    assert np.linalg.norm(v_ned - v1) < 0.03


@pytest.mark.parametrize("yaw", [0.0, 1.0, -2.5])
def test_reference_in_a_wind_balances_the_estimated_force_exactly(yaw):
    """A descent in a strong wind: the reference attitude and thrust, with the estimated drag
    taken at that attitude, give exactly the ramp's acceleration; its body velocity is the
    ramp's velocity in that tilted frame."""
    from mavreg.control.estimation.disturbance import DisturbanceEstimate
    from mavreg.model.rotation import rpy_to_matrix
    ctrl = HoverController(VEHICLE)
    ramp = plan_ramp([0, 0, -10.0], [0, 0, 0], yaw, [0, 0, -1.0], [0, 0, 0], yaw, ctrl.params)
    t = 0.4 * ramp.duration_s
    est = DisturbanceEstimate((0.34, 0.65), (-2.4, 0.5, 0.0), 0.93)
    x_ref, u_ref = ctrl.reference(ramp, t, est)
    _, v, a, _, _, _ = ramp.sample_with_jerk(t)
    R = rpy_to_matrix(*x_ref[3:6])
    m = VEHICLE.mass_kg
    force = -u_ref[0] * R[:, 2] + m * 9.81 * np.array([0, 0, 1.0]) + est.extra_force_ned(R, v, (0.0, 0.0))
    np.testing.assert_allclose(force / m, a, atol=5e-3)          # three fixed-point passes: 2 mN
    np.testing.assert_allclose(R @ x_ref[6:9], v, atol=1e-12)
    assert np.degrees(np.arccos(R[2, 2])) > 15.0                    # leaning into 2.4 N of wind
    assert x_ref[5] == pytest.approx(yaw)
