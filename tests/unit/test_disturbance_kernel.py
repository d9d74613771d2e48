"""The observer's compiled update (observer_kernel) against its numpy update, the reference.

Random filter states and measurements (one update from the same start: estimate, applied
estimate and covariance to 1e-12 relative), the low-speed branch, the gate, non-finite
innovations, the bounds and the rate limit; and a long run of a moving, tilting vehicle fed
to both filters side by side (the rounding of the two must not grow).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.accel import ACCELERATED
from mavreg.config.disturbance import DisturbanceParams
from mavreg.config.vehicle import load_vehicle
from mavreg.control.estimation import observer_kernel as ok
from mavreg.control.estimation.disturbance import DisturbanceObserver
from mavreg.model.rotation import rpy_to_matrix

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
PARAMS = DisturbanceParams(enabled=True, vertical_force_sd_n=0.5)


def _pair():
    return DisturbanceObserver(PARAMS, VEHICLE, compiled=False), _fast()


def _fast():
    if ACCELERATED:
        return DisturbanceObserver(PARAMS, VEHICLE, compiled=True)
    obs = DisturbanceObserver(PARAMS, VEHICLE, compiled=False)   # the kernel as plain Python
    obs.compiled = True
    return obs


def _set_state(obs, theta, applied, P):
    obs.theta[:], obs.theta_applied[:], obs.P[:] = theta, applied, P
    obs._estimates = None


def _close(a, b, rel=1e-12):
    a, b = np.asarray(a), np.asarray(b)
    assert np.all(np.abs(a - b) <= rel * max(np.abs(b).max(), 1e-300)), np.abs(a - b).max()


def _random_case(rng):
    theta = np.array([rng.uniform(0, 1), rng.uniform(0, 1), *rng.normal(0, 1, 3), rng.uniform(0.8, 1.2)])
    applied = theta + rng.normal(0, 0.05, 6)
    L = rng.normal(0, 0.1, (6, 6))
    P = L @ L.T + np.diag(rng.uniform(1e-4, 0.1, 6))
    R = rpy_to_matrix(*rng.uniform([-math.pi, -1.4, -math.pi], [math.pi, 1.4, math.pi]))
    speed = rng.choice([0.3, 1.9, 2.1, 6.0])              # either side of the drag's 2 m/s
    v = speed * rng.normal(0, 1, 3) / math.sqrt(3)
    thrust = rng.uniform(2.0, 40.0)
    y = rng.normal(0, 0.004, 3) * rng.choice([1.0, 3.0])
    return theta, applied, P, R, v, thrust, y, rng.choice([0.002, 0.004, 0.001])


@pytest.mark.parametrize("seed", range(300))
def test_one_update_agrees_with_the_numpy_update(seed):
    rng = np.random.default_rng(seed)
    theta, applied, P, R, v, thrust, y, dt = _random_case(rng)
    ref, fast = _pair()
    for obs in (ref, fast):
        _set_state(obs, theta, applied, P)
        obs.update(dt, R, v, thrust, y)
    assert (fast.updates, fast.rejected) == (ref.updates, ref.rejected)
    _close(fast.theta, ref.theta)
    _close(fast.theta_applied, ref.theta_applied)
    _close(fast.P, ref.P)
    assert fast.estimate.thrust_scale == float(fast.theta[5]) and fast.applied.thrust_scale == float(fast.theta_applied[5])


def test_gate_non_finite_gap_and_bounds_take_the_same_branches():
    ref, fast = _pair()
    R, v = np.eye(3), np.array([5.0, 0.0, 0.0])
    for obs in (ref, fast):
        for _ in range(300):
            obs.update(0.002, R, v, 7.35, np.zeros(3))
        obs.update(0.002, R, v, 7.35, np.array([0.5, 0.0, 0.0]))        # refused by the gate
        obs.update(0.002, R, v, 7.35, np.array([np.nan, 0.0, 0.0]))     # skipped
        obs.update(0.2, R, v, 7.35, np.ones(3))                         # a gap: skipped
        for _ in range(3000):                                           # pushed to the force bound
            obs.update(0.002, R, v, 7.35, np.array([0.0, 0.02, 0.0]))
    assert ref.rejected >= 1 and (fast.updates, fast.rejected) == (ref.updates, ref.rejected)
    assert ref.theta[3] == PARAMS.max_force_n and fast.theta[3] == PARAMS.max_force_n
    _close(fast.theta, ref.theta, 1e-10)
    _close(fast.theta_applied, ref.theta_applied, 1e-10)
    _close(fast.P, ref.P, 1e-10)


def test_a_long_manoeuvring_run_stays_together():
    """5000 measurements of a vehicle turning and speeding up through 2 m/s, with a wind:
    the two filters' estimates agree to 1e-10 relative at the end."""
    rng = np.random.default_rng(7)
    ref, fast = _pair()
    for k in range(5000):
        t = 0.002 * k
        R = rpy_to_matrix(0.8 * math.sin(0.7 * t), 0.5 * math.sin(0.3 * t), 0.4 * t)
        v = np.array([3.0 * math.sin(0.2 * t), 2.5 * math.cos(0.15 * t), 0.5 * math.sin(t)])
        y = rng.normal(0.0, 0.004, 3) + 0.002 * np.array([0.5, -0.3, 0.1]) / VEHICLE.mass_kg
        thrust = 7.35 + math.sin(3 * t)
        ref.update(0.002, R, v, thrust, y)
        fast.update(0.002, R, v, thrust, y)
    assert fast.updates == ref.updates > 4900
    _close(fast.theta, ref.theta, 1e-10)
    _close(fast.theta_applied, ref.theta_applied, 1e-10)
    _close(fast.P, ref.P, 1e-10)


def test_the_kernel_layout_matches_the_observer():
    obs = DisturbanceObserver(PARAMS, VEHICLE, compiled=False)
    assert np.shares_memory(obs.theta, obs._kf) and np.shares_memory(obs.theta_applied, obs._kf)
    assert obs._kf.shape == (ok.ROWS, 6)
    obs.theta[0] = 0.9
    obs.reset()
    assert obs.theta[0] == VEHICLE.rotor_drag_n_s_per_m[0] and np.shares_memory(obs.theta, obs._kf)
