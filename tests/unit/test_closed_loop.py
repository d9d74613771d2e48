"""Closed-loop simulator: analytic cases, LQR recovery, actuator effects, zero-order hold."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from mavreg.config.vehicle import G
from mavreg.model.linearize import model_jacobians
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.closed_loop import SimOptions, SimStatus, simulate, window_force

MODEL = QuadrotorModel(0.749, (0.0176, 0.0177, 0.034))
MIXER = Mixer(0.30, 0.016)
HOVER_ROTOR_N = MODEL.mass_kg * G / 4


def constant(forces):
    forces = np.asarray(forces, dtype=float)
    return lambda t, x: forces


def test_hover_stays_put():
    x0 = np.zeros(12)
    x0[0:3] = (1.0, -2.0, -3.0)
    res = simulate(MODEL, MIXER, constant([HOVER_ROTOR_N] * 4),
                   SimOptions(initial_state=x0, max_duration_s=2.0))
    assert res.status is SimStatus.TIMEOUT and res.stable and not res.completed
    assert res.t.shape == (2001,) and res.x.shape == (2001, 12)
    assert np.abs(res.x - x0).max() < 1e-12


def test_free_fall_matches_the_parabola():
    x0 = np.zeros(12)
    x0[2] = -100.0
    res = simulate(MODEL, MIXER, constant(np.zeros(4)),
                   SimOptions(initial_state=x0, dt_s=1e-2, max_duration_s=3.0))
    z = x0[2] + 0.5 * G * res.t ** 2
    np.testing.assert_allclose(res.x[:, 2], z, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res.x[:, 8], G * res.t, rtol=0, atol=1e-10)
    assert np.abs(res.x[:, [0, 1, 3, 4, 5, 6, 7, 9, 10, 11]]).max() == 0.0


def test_torque_free_spin_conserves_energy_and_angular_momentum():
    J = np.diag(MODEL.inertia_kg_m2)
    x0 = np.zeros(12)
    x0[9], x0[11] = 1.5, 2.0                       # roll and yaw rate, no pitch rate
    res = simulate(MODEL, MIXER, constant(np.zeros(4)),
                   SimOptions(initial_state=x0, max_duration_s=2.0))
    assert res.status is SimStatus.TIMEOUT, res.reason
    w = res.x[:, 9:12]
    assert np.abs(w[:, 1]).max() > 0.1               # gyroscopic coupling moves q
    energy = 0.5 * np.einsum("ki,ij,kj->k", w, J, w)
    h_body = w @ J
    assert np.abs(energy / energy[0] - 1).max() < 1e-10
    assert np.abs(np.linalg.norm(h_body, axis=1) / np.linalg.norm(h_body[0]) - 1).max() < 1e-10
    # The inertial angular momentum R J w is constant too (checks the Euler kinematics).
    h_inertial = np.stack([rpy_to_matrix(*x[3:6]) @ J @ x[9:12] for x in res.x])
    assert np.abs(h_inertial - h_inertial[0]).max() < 1e-9 * np.linalg.norm(h_inertial[0])


def hover_lqr():
    u_h = MODEL.hover_input()
    A, B = model_jacobians(MODEL.f, np.zeros(12), u_h)
    Q = np.diag([10, 10, 10, 1, 1, 1, 1, 1, 1, 0.1, 0.1, 0.1])
    R = np.diag([0.1, 1.0, 1.0, 1.0])
    P = scipy.linalg.solve_continuous_are(A, B, Q, R)
    K = np.linalg.solve(R, B.T @ P)
    return lambda t, x: MIXER.to_rotors(u_h - K @ x)


def test_hover_lqr_recovers_from_an_offset():
    x0 = np.zeros(12)
    x0[0:3] = 0.5
    res = simulate(MODEL, MIXER, hover_lqr(),
                   SimOptions(initial_state=x0, control_period_steps=2, max_duration_s=8.0,
                              inertia_kg_m2=(0.02, 0.015, 0.03)))
    assert res.stable
    assert np.linalg.norm(res.x[-1, 0:3]) < 1e-3
    assert np.abs(res.x[-1, 3:]).max() < 1e-3


def test_done_stops_the_run():
    x0 = np.zeros(12)
    x0[0:3] = 0.5
    res = simulate(MODEL, MIXER, hover_lqr(),
                   SimOptions(initial_state=x0, max_duration_s=8.0,
                              done=lambda t, x: np.linalg.norm(x[0:3]) < 0.05))
    assert res.status is SimStatus.COMPLETED and res.completed
    assert np.linalg.norm(res.x[-1, 0:3]) < 0.05 <= np.linalg.norm(res.x[-2, 0:3])
    assert res.t[-1] < 8.0


def test_saturation_clips_each_rotor_to_zero_and_the_limit():
    res = simulate(MODEL, MIXER, constant([20.0, -5.0, 3.0, 10.0]),
                   SimOptions(saturation_n=8.5, max_duration_s=0.01))
    np.testing.assert_array_equal(res.rotor_command_n[0], [20.0, -5.0, 3.0, 10.0])
    np.testing.assert_array_equal(res.rotor_applied_n, np.tile([8.5, 0.0, 3.0, 8.5], (11, 1)))
    res = simulate(MODEL, MIXER, constant([20.0, -5.0, 3.0, 10.0]), SimOptions(max_duration_s=0.01))
    np.testing.assert_array_equal(res.rotor_applied_n[0], [20.0, 0.0, 3.0, 10.0])


@pytest.mark.parametrize("redraw", ["physics", "control"])
def test_rotor_noise_has_the_right_sd(redraw):
    x0 = np.zeros(12)
    x0[2] = -1000.0
    period = 5
    opt = SimOptions(initial_state=x0, rotor_noise_sd_n=0.1, noise_redraw=redraw,
                     control_period_steps=period, seed=7,
                     max_duration_s=2.0 if redraw == "physics" else 4.0)
    res = simulate(MODEL, MIXER, constant([HOVER_ROTOR_N] * 4), opt)
    noise = res.rotor_applied_n[:-1] - HOVER_ROTOR_N
    if redraw == "control":
        assert np.all(noise[::period] == noise[period - 1::period])     # held per period
        noise = noise[::period]
    assert noise.size >= 3200
    assert abs(noise.std() / 0.1 - 1) < 0.05
    assert abs(noise.mean()) < 0.01
    # Same seed, same run.
    again = simulate(MODEL, MIXER, constant([HOVER_ROTOR_N] * 4), opt)
    np.testing.assert_array_equal(again.x, res.x)


def test_zero_order_hold_calls_the_controller_at_the_configured_rate():
    calls = []

    def controller(t, x):
        calls.append(t)
        return np.full(4, HOVER_ROTOR_N + 0.01 * len(calls))

    res = simulate(MODEL, MIXER, controller,
                   SimOptions(dt_s=1e-3, control_period_steps=4, max_duration_s=0.1))
    assert res.controller_calls == len(calls) == 25
    np.testing.assert_allclose(calls, 0.004 * np.arange(25), atol=1e-12)
    cmd = res.rotor_command_n[:-1, 0]
    np.testing.assert_allclose(cmd, HOVER_ROTOR_N + 0.01 * (1 + np.arange(100) // 4))


def test_external_force_window_pushes_the_vehicle():
    # 1 N east for 0.5 s on a level hover: dv = F t / m, then coasting.
    m = MODEL.mass_kg
    res = simulate(MODEL, MIXER, constant([HOVER_ROTOR_N] * 4),
                   SimOptions(force_fn=window_force([0.0, 1.0, 0.0], 0.0, 0.5),
                              max_duration_s=1.0))
    np.testing.assert_allclose(res.x[-1, 7], 0.5 / m, rtol=1e-9)
    np.testing.assert_allclose(res.x[-1, 1], 0.125 / m + 0.5 * 0.5 / m, rtol=1e-9)
    # Rolled 90 deg, no thrust: an NED upward force m g must cancel gravity exactly, which
    # holds only if the force is rotated into the body frame like gravity is.
    x0 = np.zeros(12)
    x0[3] = np.pi / 2
    res = simulate(MODEL, MIXER, constant(np.zeros(4)),
                   SimOptions(initial_state=x0, force_fn=lambda t, x: np.array([0.0, 0.0, -m * G]),
                              max_duration_s=0.5))
    assert np.abs(res.x[-1, 0:3]).max() < 1e-12            # the force cancels gravity


def test_divergence_is_detected_with_a_reason():
    x0 = np.zeros(12)
    x0[2] = -1000.0
    res = simulate(MODEL, MIXER, constant(np.zeros(4)),
                   SimOptions(initial_state=x0, max_duration_s=10.0))
    assert res.status is SimStatus.DIVERGED and not res.stable
    assert "speed" in res.reason
    assert res.t[-1] == pytest.approx(50.0 / G, abs=2e-3)
    assert res.x.shape[0] == res.t.shape[0] == res.rotor_applied_n.shape[0]
    res = simulate(MODEL, MIXER, constant([np.nan] * 4), SimOptions())
    assert res.status is SimStatus.DIVERGED and "non-finite" in res.reason


def test_options_are_validated_and_frozen():
    with pytest.raises(ValueError, match="control_period_steps"):
        SimOptions(control_period_steps=0)
    with pytest.raises(ValueError, match="initial_state"):
        SimOptions(initial_state=(0.0,) * 11)
    with pytest.raises(ValueError, match="noise_redraw"):
        SimOptions(noise_redraw="sometimes")
    opt = SimOptions(initial_state=np.ones(12))
    assert opt.initial_state == (1.0,) * 12
    with pytest.raises(Exception):
        opt.dt_s = 1.0


def test_thrust_scale_weakens_the_rotors():
    """Rotors giving 90 % of their command: the hover command leaves 10 % of g unbalanced."""
    hover = MODEL.mass_kg * 9.81 / 4
    opts = SimOptions(initial_state=(0, 0, -5) + (0.0,) * 9, max_duration_s=0.2, thrust_scale=0.9)
    run = simulate(MODEL, MIXER, lambda t, x: np.full(4, hover), opts)
    assert run.x[-1, 8] == pytest.approx(0.1 * 9.81 * run.t[-1], rel=1e-6)   # body z velocity (down)
