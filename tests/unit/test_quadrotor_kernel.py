"""The compiled RK4 steps of the design model (:func:`mavreg.model.quadrotor_kernel.rk4_step`,
roll-pitch-yaw, and :func:`~mavreg.model.quadrotor_kernel.rk4_so3_step`, a rotation matrix)
against the numpy steps of the sequential simulator (:mod:`mavreg.sim.plant_step`), their
reference."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.accel import ACCELERATED
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.sim.plant_step import RpyStep, So3Step

pytestmark = pytest.mark.skipif(not ACCELERATED, reason="numba is not in use: no compiled step")

PLANT = QuadrotorModel(1.1, (0.021, 0.019, 0.04), rotor_drag_n_s_per_m=(0.3, 0.5), parasitic_drag_n_s2_per_m2=0.02,
                       rotor_drag_thrust_exponent=0.5)


@pytest.mark.parametrize("step", [RpyStep, So3Step], ids=["rpy", "so3"])
@pytest.mark.parametrize("force", [None, np.array([2.0, -1.5, 0.7])], ids=["no force", "a gust"])
def test_the_compiled_step_follows_the_numpy_step_for_two_seconds(force, step):
    """Two seconds of 1 ms steps through a tumbling, thrusting, dragged flight (rates up to
    4 rad/s, the input changing every step): the two stay within 1e-9."""
    fast, ref = step(PLANT, compiled=True), step(PLANT, compiled=False)
    x = np.array([0.5, -1.0, -3.0, 0.2, -0.3, 1.0, 3.0, -1.0, 0.5, 1.5, -2.0, 0.8])
    y = x.copy()
    rng = np.random.default_rng(7)
    for k in range(2000):
        u = np.array([12.0 + 3.0 * np.sin(k / 50), *rng.normal(0.0, 0.05, 3)])
        x, y = fast(x, u, force, 1e-3), ref(y, u, force, 1e-3)
    assert np.abs(x - y).max() < 1e-9
    assert np.abs(x[9:12]).max() > 0.5 and np.abs(x[6:9]).max() > 1.0       # it flew somewhere


def test_a_step_that_left_out_the_force_would_be_seen():
    """The negative control: the gust's step differs from the calm one by far more than the
    tolerance, on both paths alike."""
    x = np.array([0.0, 0.0, -3.0, 0.1, 0.2, 0.3, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    u = np.array([10.0, 0.0, 0.0, 0.0])
    gust = np.array([2.0, -1.5, 0.7])
    for compiled in (True, False):
        for kind in (RpyStep, So3Step):
            step = kind(PLANT, compiled=compiled)
            d = step(x, u, gust, 0.01) - step(x, u, None, 0.01)
            assert np.abs(d[6:9]).max() > 1e-3


def test_the_rotation_matrix_step_flies_through_ninety_degrees_of_pitch():
    """A constant pitch rate through the Euler singularity: the compiled SO(3) step keeps R a
    rotation (R^T R = I to 1e-12) and its pitch is the analytic one, where roll-pitch-yaw
    could not be integrated."""
    plant = QuadrotorModel(1.0, (0.02, 0.02, 0.04))
    step = So3Step(plant, compiled=True)
    x = np.zeros(12)
    x[10] = 2.0                               # q = 2 rad/s, no torque: it keeps turning
    for _ in range(1000):
        x = step(x, np.zeros(4), None, 1e-3)
    R = step.R
    assert np.abs(R.T @ R - np.eye(3)).max() < 1e-12
    c, s = np.cos(2.0), np.sin(2.0)           # 2 rad of pitch about body y
    np.testing.assert_allclose(R, [[c, 0, s], [0, 1, 0], [-s, 0, c]], atol=1e-9)
