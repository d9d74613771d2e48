"""The transverse system augmented with the rotor lag: consistency, Jacobians, Riccati limit."""
import dataclasses

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.control.design.actuator import NZ, augmented_jacobians, augmented_rhs
from mavreg.control.design.riccati import care
from mavreg.maneuver.gain_schedule import du_ds
from mavreg.maneuver.nominal_grid import nominal_on_grid
from mavreg.maneuver.plan import build_profiles
from mavreg.planning.plan_io import plan_file
from mavreg.config.maneuver import load_maneuver
from mavreg.geometry.build import build_path
from mavreg.model.quadrotor import QuadrotorModel

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
MODEL = QuadrotorModel.from_vehicle(VEHICLE)
TAU = 0.02


@pytest.fixture(scope="module")
def roll():
    spec = load_maneuver(maneuver_file("barrel_roll"))
    path = build_path(spec)
    speed, yaw = build_profiles(spec, path)
    s = np.linspace(0.5, path.length_m - 0.5, 400)
    F, k, x, u, dx, v, _ = nominal_on_grid(MODEL, path, speed, yaw, s, "fixed")
    du = du_ds(u, s, periodic=False)
    return F, k, x, u, dx, du, v


def test_nominal_is_an_equilibrium_of_the_augmented_system(roll):
    F, k, x, u, dx, du, v = roll
    out = augmented_rhs(MODEL, TAU, F, k, x, u, dx, du, v, np.zeros((len(x), NZ)), np.zeros((len(x), 4)))
    assert np.abs(out).max() < 1e-9


def test_jacobians_match_central_differences(roll):
    F, k, x, u, dx, du, v = roll
    sel = slice(150, 156)                    # inside the loop
    args = (MODEL, TAU, F[sel], k[sel], x[sel], u[sel], dx[sel], du[sel], v[sel])
    A, B = augmented_jacobians(*args)
    n = A.shape[0]
    h = 1e-6
    z0, n0 = np.zeros((n, NZ)), np.zeros((n, 4))
    for j in range(NZ):
        dz = np.zeros((n, NZ))
        dz[:, j] = h
        col = (augmented_rhs(*args, z0 + dz, n0) - augmented_rhs(*args, z0 - dz, n0)) / (2 * h)
        np.testing.assert_allclose(A[:, :, j], col, atol=1e-5 * max(1.0, np.abs(col).max()))
    for j in range(4):
        dn = np.zeros((n, 4))
        dn[:, j] = h
        col = (augmented_rhs(*args, z0, n0 + dn) - augmented_rhs(*args, z0, n0 - dn)) / (2 * h)
        np.testing.assert_allclose(B[:, :, j], col, rtol=1e-6, atol=1e-9)


def test_lag_block_is_the_first_order_lag_in_s(roll):
    F, k, x, u, dx, du, v = roll
    A, B = augmented_jacobians(MODEL, TAU, F[:3], k[:3], x[:3], u[:3], dx[:3], du[:3], v[:3])
    for i in range(3):
        np.testing.assert_allclose(A[i, 11:, 11:], -np.eye(4) / (TAU * v[i]), rtol=1e-10)
        np.testing.assert_allclose(B[i, 11:, :], np.eye(4) / (TAU * v[i]), rtol=1e-10)
        np.testing.assert_allclose(B[i, :11, :], 0.0, atol=1e-14)


def test_steady_line_gain_is_the_augmented_care_and_lag_aware_plan_flies():
    """At the end of the barrel roll (a steady line) the swept gain equals the CARE of the
    augmented pair, and the (4, 15) schedule exists along the whole maneuver."""
    ctl = dataclasses.replace(load_controller(REAL_CONTROLLER))
    plan = plan_file(maneuver_file("barrel_roll"), VEHICLE, ctl)
    assert plan.K.shape[1:] == (4, NZ) and plan.rotor_time_constant_s == TAU
    spec = load_maneuver(maneuver_file("barrel_roll"))
    path = build_path(spec)
    speed, yaw = build_profiles(spec, path)
    s = plan.s[-3:]
    Fn, kn, xn, un, dxn, vn, _ = nominal_on_grid(MODEL, path, speed, yaw, s, "fixed")
    dun = du_ds(un, s, periodic=False)
    A, B = augmented_jacobians(MODEL, TAU, Fn, kn, xn, un, dxn, dun, vn)
    Q = np.diag(np.concatenate([ctl.q, ctl.q_wrench]))
    _, K = care(A[-1], B[-1], Q, np.diag(ctl.r))
    np.testing.assert_allclose(plan.K[-1], K, rtol=1e-6, atol=1e-6 * np.abs(K).max())
