"""The design model (eqs 6-17), rotations and the mixer against analytic cases."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.config.vehicle import G, load_vehicle
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import (matrix_to_rpy, quat_to_matrix, quat_to_rpy, rpy_to_matrix,
                                   rpy_to_quat, wrap_angle)

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
MODEL = QuadrotorModel.from_vehicle(VEHICLE)
E3 = np.array([0.0, 0.0, 1.0])

angle = st.floats(-np.pi, np.pi, allow_nan=False)
pitch = st.floats(-1.5, 1.5, allow_nan=False)   # away from the ZYX gimbal lock at +-pi/2
vec3 = st.lists(st.floats(-5.0, 5.0, allow_nan=False), min_size=3, max_size=3).map(np.array)


@given(angle, vec3)
def test_hover_at_mg_is_an_equilibrium(psi, pos):
    x = np.zeros(12)
    x[:3] = pos
    x[5] = psi   # any yaw, level
    dx = MODEL.f(x, MODEL.hover_input())
    np.testing.assert_allclose(dx, 0.0, atol=1e-12)
    assert MODEL.hover_input()[0] == pytest.approx(VEHICLE.mass_kg * G)


@given(angle, pitch, angle, vec3)
def test_free_fall_accelerates_at_g_along_body_down(phi, theta, psi, v):
    x = np.zeros(12)
    x[3:6] = phi, theta, psi
    x[6:9] = v
    dx = MODEL.f(x, np.zeros(4))
    R = rpy_to_matrix(phi, theta, psi)
    np.testing.assert_allclose(dx[6:9], G * R.T @ E3, atol=1e-12)
    # and in the inertial frame the acceleration is g e3 (d/dt of R v with omega = 0)
    np.testing.assert_allclose(R @ dx[6:9], G * E3, atol=1e-12)
    np.testing.assert_allclose(dx[:3], R @ v, atol=1e-12)


@settings(max_examples=50)
@given(vec3)
def test_torque_free_spin_conserves_energy_and_angular_momentum(w):
    """Euler's equations J w' = -w x J w: the gyroscopic coupling does no work and only
    rotates the body-frame angular momentum, so 1/2 w.Jw and |Jw| are constant."""
    J = np.array(VEHICLE.inertia_kg_m2)
    x = np.zeros(12)
    x[9:12] = w
    wdot = MODEL.f(x, np.zeros(4))[9:12]
    # the coupling is really there for a generic spin (jx != jy != jz)
    np.testing.assert_allclose(wdot, -np.cross(w, J * w) / J, rtol=1e-12, atol=1e-12)
    energy = lambda om: 0.5 * om @ (J * om)
    momentum = lambda om: np.linalg.norm(J * om)
    h = 1e-6
    scale = 1.0 + w @ w
    for q in (energy, momentum):
        rate = (q(w + h * wdot) - q(w - h * wdot)) / (2 * h)
        assert abs(rate) < 1e-6 * scale


def test_spin_about_a_principal_axis_is_steady():
    for i in range(3):
        x = np.zeros(12)
        x[9 + i] = 7.0
        np.testing.assert_allclose(MODEL.f(x, np.zeros(4))[9:12], 0.0, atol=1e-12)


@given(angle, pitch, angle)
def test_rotation_matrix_is_orthonormal_and_proper(phi, theta, psi):
    R = rpy_to_matrix(phi, theta, psi)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


@given(angle, pitch, angle)
def test_rpy_round_trip(phi, theta, psi):
    back = matrix_to_rpy(rpy_to_matrix(phi, theta, psi))
    np.testing.assert_allclose(wrap_angle(back - np.array([phi, theta, psi])), 0.0, atol=1e-9)


@given(angle, pitch, angle)
def test_quaternion_round_trip(phi, theta, psi):
    q = rpy_to_quat(phi, theta, psi)
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(quat_to_matrix(q), rpy_to_matrix(phi, theta, psi), atol=1e-12)
    np.testing.assert_allclose(wrap_angle(quat_to_rpy(q) - np.array([phi, theta, psi])), 0.0,
                               atol=1e-9)


def test_rotation_convention_body_to_ned():
    # yaw 90 deg: body x (nose) points east; roll 90 deg: body y (right) points down
    np.testing.assert_allclose(rpy_to_matrix(0, 0, np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rpy_to_matrix(np.pi / 2, 0, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-15)


@given(st.lists(st.floats(-20.0, 20.0, allow_nan=False), min_size=4, max_size=4))
def test_mixer_round_trip(rotors):
    mix = Mixer.from_vehicle(VEHICLE)
    rotors = np.array(rotors)
    np.testing.assert_allclose(mix.to_rotors(mix.to_wrench(rotors)), rotors, atol=1e-9)
    u = mix.to_wrench(rotors)
    np.testing.assert_allclose(mix.to_wrench(mix.to_rotors(u)), u, atol=1e-9)


def test_hover_rotor_forces_are_a_quarter_of_mg_each():
    mix = Mixer.from_vehicle(VEHICLE)
    np.testing.assert_allclose(mix.to_rotors(MODEL.hover_input()),
                               np.full(4, VEHICLE.mass_kg * G / 4), rtol=1e-12)


def test_model_accepts_a_batch():
    rng = np.random.default_rng(0)
    X = rng.normal(size=(12, 5))
    U = rng.normal(size=(4, 5))
    batch = MODEL.f(X, U)
    for j in range(5):
        np.testing.assert_allclose(batch[:, j], MODEL.f(X[:, j], U[:, j]), rtol=1e-13)


def test_lift_to_zero_keeps_the_torques_and_only_adds_thrust():
    from mavreg.model.mixer import Mixer, lift_to_zero
    mix = Mixer(0.3, 0.016)
    f = np.array([2.0, -0.8, 3.0, 1.5])
    g = lift_to_zero(f, 12.0)
    assert g.min() == pytest.approx(0.0)
    np.testing.assert_allclose(mix.to_wrench(g)[1:], mix.to_wrench(f)[1:], atol=1e-12)
    assert mix.to_wrench(g)[0] == pytest.approx(mix.to_wrench(f)[0] + 4 * 0.8)
    ok = np.array([0.5, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(lift_to_zero(ok, 12.0), ok)
    # No room at the top: lifted only as far as the limit allows
    np.testing.assert_allclose(lift_to_zero(np.array([11.5, -1.0, 5.0, 5.0]), 12.0), [12.0, -0.5, 5.5, 5.5])


def test_yaw_gives_way_before_the_collective_is_lifted():
    from mavreg.model.mixer import Mixer, yaw_then_lift
    mix = Mixer(0.3, 0.016)
    # roll, pitch and thrust alone keep every rotor >= 0; the yaw torque would pull rotor 1
    u = np.array([6.0, 0.3, 0.2, -0.12])
    assert (mix.inverse @ u).min() < 0
    f = yaw_then_lift(mix.inverse, u, 12.0)
    w = mix.to_wrench(f)
    assert f.min() == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(w[:3], u[:3], atol=1e-12)          # thrust, roll, pitch kept
    assert -0.12 < w[3] < 0.0                                       # yaw reduced, same sign
    # enough margin: nothing changes
    easy = np.array([20.0, 0.3, 0.2, -0.05])
    np.testing.assert_allclose(yaw_then_lift(mix.inverse, easy, 12.0), mix.inverse @ easy, atol=1e-12)
    # roll alone pulls a rotor: no yaw left, then the collective lifts, roll and pitch kept
    hard = np.array([2.0, 1.0, 0.0, 0.05])
    g = yaw_then_lift(mix.inverse, hard, 12.0)
    wg = mix.to_wrench(g)
    assert g.min() == pytest.approx(0.0, abs=1e-12) and wg[3] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(wg[1:3], hard[1:3], atol=1e-12)
    assert wg[0] > hard[0]
