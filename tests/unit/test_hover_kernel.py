"""The hover controller's compiled step (hover_kernel) against its numpy step, the reference.

Random states about random ramps (before their start, inside, at and past their end, with a
moving end), with and without a disturbance estimate fed forward, and the states of a
closed-loop hover flown with the observer: u, the rotor forces and the error agree to 1e-12
relative (of each vector's size), and the rotors' low-end branch (yaw given up, then all
four lifted) is taken alike.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from mavreg.accel import ACCELERATED
from mavreg.control.estimation.disturbance import DisturbanceEstimate
from mavreg.control.controllers.hover import HoverController, HoverParams, hold_ramp, plan_ramp

from harness import controller_flight as flight
from harness import params

VEHICLE = params.vehicle()


def _pair():
    ref = HoverController(VEHICLE, HoverParams(), compiled=False)
    fast = HoverController(VEHICLE, HoverParams(), compiled=False)
    fast._compiled = True             # compiled where numba is, else the kernels as plain Python
    return ref, fast


def _agree(a, b):
    for name in ("u", "rotor_forces_n", "error"):
        va, vb = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert va.shape == vb.shape
        assert np.abs(va - vb).max() <= 1e-12 * (1.0 + np.abs(vb).max()), (name, va, vb)


def _ramp(rng):
    if rng.random() < 0.2:
        return hold_ramp(rng.normal(0, 2, 3), rng.uniform(-math.pi, math.pi))
    p0, p1 = rng.normal(0, 2, 3), rng.normal(0, 2, 3)
    along = (p1 - p0) / np.linalg.norm(p1 - p0)
    v1 = rng.uniform(0.1, 0.8) * along if rng.random() < 0.5 else np.zeros(3)    # a moving end
    return plan_ramp(p0, np.zeros(3), rng.uniform(-3, 3), p1, v1, rng.uniform(-3, 3), HoverParams())


@pytest.mark.parametrize("seed", range(60))
def test_random_states_and_ramps_agree_with_the_numpy_step(seed):
    rng = np.random.default_rng(seed)
    ref, fast = _pair()
    ramp = _ramp(rng)
    torque = (0.0,) * 6 if seed % 2 else (*rng.normal(0, 0.05, 3), *rng.normal(0, 0.01, 3))
    est = None if seed % 3 == 0 else DisturbanceEstimate((rng.uniform(0, 1), rng.uniform(0, 1)),
                                                         tuple(rng.normal(0, 1.5, 3)), rng.uniform(0.8, 1.2), torque)
    for t in (-0.2, 0.0, *rng.uniform(0, ramp.duration_s, 5), ramp.duration_s, ramp.duration_s + 1.3):
        x = np.concatenate([ramp.sample(t)[0] + rng.normal(0, 0.3, 3), rng.normal(0, 0.3, 3),
                            rng.normal(0, 1, 3), rng.normal(0, 1, 3)])
        x[5] += ramp.sample(t)[3] + rng.choice([0.0, 2 * math.pi, -2 * math.pi])   # yaw on another branch
        _agree(fast.step(x, ramp, t, est), ref.step(x, ramp, t, est))


def test_the_rotors_low_end_branch_is_taken_alike():
    ref, fast = _pair()
    ramp = hold_ramp(np.zeros(3), 0.0)
    plain = 0
    for k in range(40):
        x = np.zeros(12)
        x[2] = -0.1 * k                   # above the point: little thrust
        if k % 2:
            x[9:12] = (2.0, -1.5, 5.0 * (k % 3 - 1))
        a, b = fast.step(x, ramp, 0.0), ref.step(x, ramp, 0.0)
        _agree(a, b)
        plain += bool(np.allclose(b.rotor_forces_n, ref.mixer.inverse @ b.u))
    assert 0 < plain < 40             # some states needed the yaw given up or the rotors lifted


def test_a_closed_loop_hover_agrees_state_by_state():
    setup = flight.Setup()
    samples = flight.fly(setup, "hover", 3.0)
    ramp = flight.hover_ramp(samples[0][1])
    ref, fast = _pair()
    est = DisturbanceEstimate((0.3, 0.1), (0.3, 0.5, 0.0), 1.02)
    for t, x, _, _ in samples[::5]:
        _agree(fast.step(x, ramp, t, est), ref.step(x, ramp, t, est))


def test_compiled_is_the_default_where_numba_is():
    assert HoverController(VEHICLE)._compiled == ACCELERATED
    if not ACCELERATED:
        with pytest.raises(ValueError):
            HoverController(VEHICLE, compiled=True)
