"""The recovery controller on a quaternion rigid body that is not the design model.

The plant is firmware_sim's quaternion RK4 (imported here, in a test only: mavreg itself
never imports firmware_sim) with a 20 ms first-order rotor lag, stepped at 1 kHz with the
controller at 500 Hz. The controller is always designed on the nominal MK-Quadro.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from firmware_sim.physics import RigidBody, inertia_matrix, quat_from_euler
from firmware_sim.rotors import Rotors, mix
from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.config.envelope import RecoveryParams
from mavreg.config.vehicle import load_vehicle
from mavreg.control.controllers.recovery import RecoveryController, allocate, attitude_error, heading_rad, tilt_rad
from mavreg.model.mixer import Mixer
from mavreg.model.rotation import quat_to_matrix, rpy_to_matrix

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
MIXER = Mixer.from_vehicle(VEHICLE)
FMAX = VEHICLE.max_rotor_thrust_n


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# ------------------------------------------------------------------ attitude error
@given(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.floats(0.0, math.pi),
       st.floats(-3, 3), st.floats(-1.5, 1.5), st.floats(-3, 3))
@settings(max_examples=200, deadline=None)
def test_attitude_error_is_angle_times_axis(ax, ay, az, angle, r, p, y):
    axis = np.array([ax, ay, az])
    if np.linalg.norm(axis) < 0.1:
        return
    axis /= np.linalg.norm(axis)
    R_d = rpy_to_matrix(r, p, y)
    R = R_d @ _rot(axis, angle)            # rotated by `angle` about the body axis
    e = attitude_error(R_d, R)
    assert abs(np.linalg.norm(e) - angle) < 1e-6
    if 1e-3 < angle < math.pi - 1e-3:
        assert np.allclose(e, angle * axis, atol=1e-6)


def test_attitude_error_upside_down_is_not_zero():
    """Lee's sin(theta) error vanishes at pi; theta * n does not."""
    for axis in ([1, 0, 0], [0, 1, 0], [1, 1, 0]):
        e = attitude_error(np.eye(3), _rot(axis, math.pi))
        assert abs(np.linalg.norm(e) - math.pi) < 1e-9
        n = np.asarray(axis, float) / np.linalg.norm(axis)
        assert abs(abs(e @ n) - math.pi) < 1e-6


def test_tilt_and_heading_from_matrices():
    assert tilt_rad(np.eye(3)) == 0.0
    assert abs(tilt_rad(rpy_to_matrix(math.pi, 0, 0.3)) - math.pi) < 1e-9
    assert abs(heading_rad(rpy_to_matrix(0.2, 0.1, 1.0)) - 1.0) < 1e-9
    assert abs(heading_rad(rpy_to_matrix(math.pi, 0, -2.0)) + 2.0) < 1e-9   # inverted
    assert abs(heading_rad(rpy_to_matrix(0, math.pi / 2, 0.7)) - 0.7) < 1e-6  # nose up


# ------------------------------------------------------------------ allocation
def test_allocation_exact_when_feasible():
    u = np.array([9.0, 0.2, -0.3, 0.01])
    f = allocate(u[0], u[1:], MIXER.inverse, FMAX)
    assert np.allclose(MIXER.to_wrench(f), u)


def test_allocation_gives_up_collective_first():
    tau = np.array([1.5, 0.0, 0.0])                      # needs f4 - f2 = 5 N
    f = allocate(60.0, tau, MIXER.inverse, FMAX)         # more collective than possible
    w = MIXER.to_wrench(f)
    assert np.allclose(w[1:], tau) and w[0] < 60.0 and f.max() == pytest.approx(FMAX)
    f = allocate(-5.0, tau, MIXER.inverse, FMAX)         # inverted: collective as low as the torque allows
    w = MIXER.to_wrench(f)
    assert np.allclose(w[1:], tau) and f.min() == pytest.approx(0.0)
    assert w[0] == pytest.approx(2 * 1.5 / VEHICLE.arm_length_m)


def test_allocation_drops_yaw_before_roll_and_pitch():
    tau = np.array([2.0, 1.0, 0.3])                      # yaw far beyond 2 k fmax with that roll
    f = allocate(20.0, tau, MIXER.inverse, FMAX)
    w = MIXER.to_wrench(f)
    assert np.allclose(w[1:3], tau[:2]) and 0.0 <= w[3] < tau[2]
    tau = np.array([6.0, 3.0, 0.2])                      # roll/pitch alone infeasible
    w = MIXER.to_wrench(allocate(20.0, tau, MIXER.inverse, FMAX))
    assert abs(w[3]) < 1e-9
    assert w[1] / w[2] == pytest.approx(2.0) and w[1] < 6.0   # direction kept, scaled down


@given(st.floats(-50, 100), st.floats(-10, 10), st.floats(-10, 10), st.floats(-2, 2))
@settings(max_examples=300, deadline=None)
def test_allocation_always_within_limits(f, t1, t2, t3):
    forces = allocate(f, [t1, t2, t3], MIXER.inverse, FMAX)
    assert np.all(forces >= 0.0) and np.all(forces <= FMAX)
    w = MIXER.to_wrench(forces)
    # roll/pitch direction never reverses
    assert w[1] * t1 >= -1e-9 and w[2] * t2 >= -1e-9


# ------------------------------------------------------------------ closed loop
def fly(roll_deg=0.0, pitch_deg=0.0, v_ned=(0.0, 8.0, 0.0), z=-10.0, rates=(0.0, 0.0, 0.0),
        mass_scale=1.0, inertia_scale=1.0, seconds=8.0, ground_z=0.0, force_ned=(0.0, 0.0, 0.0)):
    """Recover from the given state; returns per-step (t, position, velocity, tilt) arrays."""
    params = RecoveryParams()
    body = RigidBody(VEHICLE.mass_kg * mass_scale,
                     inertia_matrix([j * inertia_scale for j in VEHICLE.inertia_kg_m2], (0, 0, 0)), (0, 0, 0))
    rotors = Rotors(FMAX, 0.02, 0.0, 0.001, np.random.default_rng(0))
    rotors.lagged_n = [VEHICLE.mass_kg * 9.81 / 4] * 4
    q = quat_from_euler(math.radians(roll_deg), math.radians(pitch_deg), 0.0)
    s = (0.0, 0.0, z, *q, *v_ned, *rates)
    ctl = RecoveryController(VEHICLE, params)
    ctl.start(np.array(s[:3]), np.array(s[7:10]), quat_to_matrix(np.array(s[3:7])), ground_z)
    out = {"t": [], "p": [], "v": [], "tilt": [], "settled": [], "forces": []}
    for k in range(int(seconds * 500)):
        R = quat_to_matrix(np.array(s[3:7]))
        o = ctl.step(k / 500, np.array(s[:3]), np.array(s[7:10]), R, np.array(s[10:13]))
        for _ in range(2):
            T, tx, ty, tz = mix(rotors.step(o.rotor_forces_n.tolist(), True), VEHICLE.arm_length_m,
                                VEHICLE.drag_torque_ratio_m)
            s = body.rk4_step(s, 0.001, T, tx, ty, tz, (0, 0, 0), force_ned)
        R = quat_to_matrix(np.array(s[3:7]))
        out["t"].append((k + 1) / 500)
        out["p"].append(s[:3])
        out["v"].append(s[7:10])
        out["tilt"].append(tilt_rad(R))
        out["settled"].append(ctl.settled(np.array(s[:3]), np.array(s[7:10]), R))
        out["forces"].append(o.rotor_forces_n)
    return {k: np.array(v) for k, v in out.items()}


def _settled_since(r):
    """First time after which the controller reports settled for good."""
    unsettled = np.flatnonzero(~r["settled"])
    return r["t"][unsettled[-1] + 1] if unsettled.size < len(r["t"]) else math.inf


def test_recovers_from_inverted_at_8_m_s():
    """Upside down at 8 m/s, 10 m up: it turns over, brakes, and holds at its altitude
    having lost at most 2.5 m on the way (measured 2.25 m), settled within 3 s."""
    r = fly(roll_deg=180.0, v_ned=(0.0, 8.0, 0.0), z=-10.0)
    loss = r["p"][:, 2].max() + 10.0
    print(f"\ninverted at 8 m/s: altitude loss {loss:.2f} m, settled at {_settled_since(r):.2f} s, "
          f"braked within {r['p'][:, 1].max():.2f} m")
    assert loss < 2.5
    assert _settled_since(r) < 3.0
    assert r["p"][:, 1].max() < 8.0                    # braked: 8 m/s stopped within 8 m
    end = r["t"] > 6.0
    assert np.all(np.linalg.norm(r["v"][end], axis=1) < 0.05)
    assert np.degrees(r["tilt"][end]).max() < 1.0
    assert np.all(np.abs(r["p"][end, 2] + 10.0) < 0.15)  # back at the altitude it started at
    assert np.all((r["forces"] >= 0) & (r["forces"] <= FMAX))


@pytest.mark.parametrize("mass_scale,inertia_scale", [(1.4, 1.0), (1.0, 3.0), (1.4, 3.0)])
def test_recovers_a_vehicle_unlike_its_design(mass_scale, inertia_scale):
    """40 % heavier and/or three times the inertia, controller on the design values: it still
    recovers from inverted at 8 m/s within the timeout, losing at most 5 m (measured 4.6 m
    for both together)."""
    r = fly(roll_deg=180.0, mass_scale=mass_scale, inertia_scale=inertia_scale)
    loss = r["p"][:, 2].max() + 10.0
    print(f"\nmass x{mass_scale}, inertia x{inertia_scale}: altitude loss {loss:.2f} m, "
          f"settled at {_settled_since(r):.2f} s")
    assert loss < 5.0
    assert _settled_since(r) < RecoveryParams().timeout_s - RecoveryParams().settle_s
    assert abs(r["p"][-1, 2] + 10.0) < 0.15


def test_climbs_to_the_safe_altitude_from_a_low_descent():
    """1.2 m up, sinking at 2 m/s and tilted 40 deg: it never reaches the ground and climbs
    to the safe altitude (3 m) above the take-off point."""
    r = fly(roll_deg=40.0, v_ned=(3.0, 0.0, 2.0), z=-1.2)
    print(f"\nlow descent: lowest altitude {-r['p'][:, 2].max():.2f} m")
    assert -r["p"][:, 2].max() > 0.3
    assert abs(r["p"][-1, 2] + RecoveryParams().safe_altitude_m) < 0.1
    assert r["settled"][-1]


def test_stops_a_tumble():
    """Tumbling at 13.7 rad/s: the rates are stopped (the torque needs so much collective
    that it climbs), then it holds the highest point it reached instead of descending."""
    r = fly(roll_deg=30.0, v_ned=(0.0, 0.0, 0.0), rates=(12.0, -6.0, 3.0), seconds=5.0)
    assert _settled_since(r) < 5.0 and np.degrees(r["tilt"][-1]) < 1.0
    assert r["p"][:, 2].max() < -10.0 + 1e-3                 # never below where it started
    apex = r["p"][:, 2].min()
    assert abs(r["p"][-1, 2] - apex) < 0.3


def test_holds_against_a_steady_wind():
    """3.5 N of side force (4.7 m/s^2, across its 8 m/s) all along: braking takes the whole
    tilt budget (35 deg) for 1.5 s, so the wind carries it about 6 m; then it holds, tilted
    into the wind, settled, drifting less than 5 cm over the last 2 s."""
    r = fly(roll_deg=0.0, v_ned=(0.0, 8.0, 0.0), force_ned=(3.5, 0.0, 0.0), seconds=10.0)
    print(f"\nsteady wind: carried {r['p'][-1, 0]:.2f} m, settled at {_settled_since(r):.2f} s, "
          f"tilted {np.degrees(r['tilt'][-1]):.1f} deg")
    assert _settled_since(r) < 4.0
    end = r["t"] > 8.0
    assert np.ptp(r["p"][end, 0]) < 0.05 and np.ptp(r["p"][end, 1]) < 0.05
    assert r["p"][:, 0].max() < 6.5
    assert abs(np.degrees(r["tilt"][-1]) - np.degrees(np.arctan(3.5 / (VEHICLE.mass_kg * 9.81)))) < 1.0
    assert abs(r["p"][-1, 2] + 10.0) < 0.15
