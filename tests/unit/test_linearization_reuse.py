"""The linearization computes the attitude terms once for the columns that keep the attitude
(:class:`mavreg.control.design.transverse.FrozenAttitude`): its A and B must be those of the plain
complex step, in which every column computes them anew, to the last bit."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.control.design.actuator import augmented_jacobians, augmented_rhs
from mavreg.control.design.transverse import NW, transverse_jacobians, transverse_rhs
from mavreg.model.linearize import complex_step_jacobian
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix

N = 40


@pytest.fixture(scope="module")
def nominal():
    rng = np.random.default_rng(11)
    ang = rng.uniform(-0.8, 0.8, size=(N, 3))
    F = np.moveaxis(rpy_to_matrix(*rng.uniform(-1, 1, size=(3, N))), -1, 0)
    xbar = np.concatenate([rng.normal(size=(N, 3)), ang, rng.normal(size=(N, 3)) + [4.0, 0, 0],
                           rng.normal(size=(N, 3))], axis=1)
    ubar = np.concatenate([rng.uniform(10, 20, size=(N, 1)), rng.normal(0, 0.1, size=(N, 3))], axis=1)
    return dict(F=F, k=rng.normal(0, 0.3, size=(N, 2)), xbar=xbar, ubar=ubar,
                dxbar=rng.normal(size=(N, 12)), Rbar=np.moveaxis(rpy_to_matrix(*ang.T), -1, 0),
                dubar=rng.normal(size=(N, 4)), speed=rng.uniform(1, 8, size=N))


def _bits(a):
    return np.ascontiguousarray(a).tobytes()


@pytest.mark.parametrize("so3", [False, True], ids=["rpy", "so3"])
def test_transverse_jacobians_equal_the_plain_complex_step(nominal, so3):
    model = QuadrotorModel(1.2, (0.01, 0.01, 0.02), rotor_drag_n_s_per_m=(0.1, 0.05))
    n = nominal
    Rbar = n["Rbar"] if so3 else None
    args = (model, n["F"], n["k"], n["xbar"], n["ubar"], n["dxbar"])
    w0, u0 = np.zeros((N, NW)), np.zeros((N, 4))
    A_plain = complex_step_jacobian(lambda w: transverse_rhs(*args, w, u0, Rbar=Rbar), w0)
    B_plain = complex_step_jacobian(lambda uw: transverse_rhs(*args, w0, uw, Rbar=Rbar), u0)
    A, B = transverse_jacobians(*args, Rbar=Rbar)
    assert _bits(A) == _bits(A_plain) and _bits(B) == _bits(B_plain)
    assert np.abs(A[:, :, 2:5]).max() > 0          # the attitude columns are there


@pytest.mark.parametrize("so3", [False, True], ids=["rpy", "so3"])
def test_lag_augmented_jacobians_equal_the_plain_complex_step(nominal, so3):
    model = QuadrotorModel(1.2, (0.01, 0.01, 0.02))
    n = nominal
    Rbar = n["Rbar"] if so3 else None
    args = (model, 0.03, n["F"], n["k"], n["xbar"], n["ubar"], n["dxbar"], n["dubar"], n["speed"])
    z0, n0 = np.zeros((N, NW + 4)), np.zeros((N, 4))
    A_plain = complex_step_jacobian(lambda z: augmented_rhs(*args, z, n0, Rbar), z0)
    B_plain = complex_step_jacobian(lambda nu: augmented_rhs(*args, z0, nu, Rbar), n0)
    A, B = augmented_jacobians(*args, Rbar=Rbar)
    assert _bits(A) == _bits(A_plain) and _bits(B) == _bits(B_plain)
