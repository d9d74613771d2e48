"""The compiled RK4 step of the design model (:func:`mavreg.model.quadrotor_kernel.rk4_step`)
against the numpy step of the sequential simulator, its reference."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.accel import ACCELERATED
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.sim.closed_loop import _RpyStep

pytestmark = pytest.mark.skipif(not ACCELERATED, reason="numba is not in use: no compiled step")

PLANT = QuadrotorModel(1.1, (0.021, 0.019, 0.04), rotor_drag_n_s_per_m=(0.3, 0.5), parasitic_drag_n_s2_per_m2=0.02,
                       rotor_drag_thrust_exponent=0.5)


@pytest.mark.parametrize("force", [None, np.array([2.0, -1.5, 0.7])], ids=["no force", "a gust"])
def test_the_compiled_step_follows_the_numpy_step_for_two_seconds(force):
    """Two seconds of 1 ms steps through a tumbling, thrusting, dragged flight (rates up to
    4 rad/s, the input changing every step): the two stay within 1e-9."""
    fast, ref = _RpyStep(PLANT, compiled=True), _RpyStep(PLANT, compiled=False)
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
        step = _RpyStep(PLANT, compiled=compiled)
        d = step(x, u, gust, 0.01) - step(x, u, None, 0.01)
        assert np.abs(d[6:9]).max() > 1e-3
