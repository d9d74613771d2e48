"""The rotor lag's one home: the numpy reference (mavreg.model.rotor_lag) against the
closed form of the ODE and against its compiled kernels (mavreg.model.rotor_lag_kernel)."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mavreg.model import rotor_lag as rl
from mavreg.model import rotor_lag_kernel as rk

F0 = np.array([1.0, 2.5, 7.0, 0.2])
C = np.array([3.0, 3.0, 0.5, 9.0])


def test_discrete_step_and_mean_solve_the_ode():
    tau, dt = 0.02, 0.013
    sol = solve_ivp(lambda t, f: rl.lag_rate(f, C, tau), (0.0, dt), F0, rtol=1e-12, atol=1e-12,
                    dense_output=True)
    decay = rl.lag_decay(dt, tau)
    assert np.allclose(rl.lag_toward(F0, C, decay), sol.y[:, -1], atol=1e-9)
    ts = np.linspace(0.0, dt, 2001)
    mean = np.trapezoid(sol.sol(ts), ts, axis=1) / dt
    assert np.allclose(rl.lag_toward(F0, C, rl.mean_fraction(dt, tau, decay)), mean, atol=1e-7)
    # negative control: the command itself is not the lagged force
    assert not np.allclose(C, sol.y[:, -1], atol=1e-3)


def test_ideal_rotors_follow_the_command():
    assert rl.lag_decay(0.01, 0.0) == 0.0 and rl.mean_fraction(0.01, 0.0, 0.0) == 0.0
    assert np.array_equal(rl.lag_toward(F0, C, 0.0), C)
    assert rk.lag_over4(*F0, *C, 0.01, 0.0) == (*C, *C)
    assert rk.lag_after4(*F0, *C, 0.01, -1.0) == tuple(C)


@pytest.mark.parametrize("dt, tau", [(0.001, 0.02), (0.013, 0.05), (0.2, 0.03)])
def test_kernel_agrees_with_the_reference(dt, tau):
    """The kernels take math.exp, the reference np.exp (they may differ by an ulp); given the
    same decay the step is the same operations, bit for bit."""
    decay = rl.lag_decay(dt, tau)
    e = math.exp(-dt / tau)
    assert decay == pytest.approx(e, rel=1e-15, abs=0.0)
    out = rk.lag_over4(*F0, *C, dt, tau)
    assert np.array_equal(np.array(out[:4]), rl.lag_toward(F0, C, e))
    assert np.array_equal(np.array(out[4:]), rl.lag_toward(F0, C, rl.mean_fraction(dt, tau, e)))
    assert np.allclose(np.array(out[:4]), rl.lag_toward(F0, C, decay), rtol=1e-14, atol=0.0)
    assert np.array_equal(np.array(rk.lag_after4(*F0, *C, dt, tau)), rl.lag_toward(F0, C, e))
    assert rk.lag_toward(F0[1], C[1], decay) == rl.lag_toward(F0, C, decay)[1]


def test_lag_augment_is_the_continuous_form():
    A, B = np.zeros((2, 2)), np.eye(2)
    Az, Bz = rl.lag_augment(A, B, 0.05)
    z, u = np.array([0.0, 0.0, 1.0, -2.0]), np.array([3.0, 4.0])
    assert np.allclose((Az @ z + Bz @ u)[2:], rl.lag_rate(z[2:], u, 0.05))
    with pytest.raises(ValueError):
        rl.lag_augment(A, B, 0.0)
