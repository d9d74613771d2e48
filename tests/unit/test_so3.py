"""SO(3) maps: round trips, the kinematics of the attitude error, complex-step safety."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.model.rotation import rpy_to_matrix
from mavreg.model.so3 import (attitude_error, exp_so3, hat, log_so3, project_to_so3,
                              right_jacobian_inv, vee)

RNG = np.random.default_rng(7)


def _random_vectors(n, max_angle):
    axes = RNG.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    return axes * RNG.uniform(0, max_angle, size=(n, 1))


def test_exp_is_a_rotation_and_log_inverts_it_up_to_pi():
    v = np.concatenate([_random_vectors(500, np.pi - 1e-6), _random_vectors(50, 1e-6),
                        np.zeros((1, 3)), _random_vectors(50, 1e-3) + 0])
    R = exp_so3(v)
    assert np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max() < 1e-14
    assert np.abs(np.linalg.det(R) - 1).max() < 1e-14
    assert np.abs(log_so3(R) - v).max() < 1e-9


def test_log_at_exactly_pi_gives_an_axis_of_length_pi():
    for axis in np.eye(3).tolist() + [list(np.ones(3) / np.sqrt(3))]:
        v = np.pi * np.asarray(axis)
        back = log_so3(exp_so3(v))
        assert np.isclose(np.linalg.norm(back), np.pi)
        assert np.abs(exp_so3(back) - exp_so3(v)).max() < 1e-12


def test_hat_vee_and_cross():
    a, b = RNG.normal(size=(2, 3))
    assert np.allclose(hat(a) @ b, np.cross(a, b))
    assert np.allclose(vee(hat(a)), a)


def test_attitude_error_through_pitch_ninety():
    """Roll-pitch-yaw differences are singular at pitch 90 deg; the SO(3) error is not:
    a 0.01 rad turn about body y from pitch 89.9 deg to 90.1 deg reads 0.01 rad (the rpy
    difference of those two attitudes is about 180 deg in roll and in yaw)."""
    R0 = rpy_to_matrix(0.0, np.radians(89.9), 0.0)
    R1 = R0 @ exp_so3(np.array([0.0, np.radians(0.2), 0.0]))
    e = attitude_error(R0, R1)
    assert np.allclose(e, [0.0, np.radians(0.2), 0.0], atol=1e-12)


def test_error_kinematics_match_a_finite_difference():
    """d/dt Log(Rbar^T R) = J_r^{-1}(e) (w - Exp(e)^T wbar)."""
    Rb = exp_so3(RNG.normal(size=3))
    e = RNG.normal(size=3) * 0.8
    w, wb = RNG.normal(size=(2, 3))
    R = Rb @ exp_so3(e)
    dt = 1e-6
    e_next = attitude_error(Rb @ exp_so3(wb * dt), R @ exp_so3(w * dt))
    e_prev = attitude_error(Rb @ exp_so3(-wb * dt), R @ exp_so3(-w * dt))
    fd = (e_next - e_prev) / (2 * dt)
    assert np.allclose(right_jacobian_inv(e) @ (w - exp_so3(e).T @ wb), fd, atol=1e-7)


def test_complex_step_through_exp_and_jacobian():
    """At e = 0 the complex step of Exp and J_r^{-1} gives their exact derivatives."""
    h = 1e-30
    for j in range(3):
        d = np.zeros(3, dtype=complex)
        d[j] = 1j * h
        assert np.allclose(exp_so3(d).imag / h, hat(np.eye(3)[j]), atol=1e-15)
        assert np.allclose(right_jacobian_inv(d).imag / h, 0.5 * hat(np.eye(3)[j]), atol=1e-15)


@pytest.mark.parametrize("noise", [1e-3, 0.1])
def test_projection_to_the_nearest_rotation(noise):
    R = exp_so3(RNG.normal(size=3))
    P = project_to_so3(R + noise * RNG.normal(size=(3, 3)))
    assert np.abs(P.T @ P - np.eye(3)).max() < 1e-14 and np.isclose(np.linalg.det(P), 1)
    assert np.abs(project_to_so3(R) - R).max() < 1e-14
