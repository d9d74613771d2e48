"""The airframe drag's one home: its numpy forms (mavreg.model.drag) against each other and
against their compiled kernels (mavreg.model.drag_kernel); the plant kernel against the
design model."""
import numpy as np
import pytest

from mavreg.model import drag, drag_kernel
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.quadrotor_kernel import angular_acceleration, plant_rhs
from mavreg.model.rotation import rpy_to_matrix

R = rpy_to_matrix(0.4, -0.7, 2.1)
V = np.array([6.0, -3.5, 1.2])
CXY, CZ, CP = 0.43, 0.68, 0.02


def test_the_forms_are_one_model():
    full = drag.drag_ned_n(R, V, CXY, CZ, CP)
    explicit = -R @ np.diag([CXY, CXY, CZ]) @ R.T @ V - CP * np.linalg.norm(V) * V
    assert np.allclose(full, explicit, atol=1e-12)
    linear = drag.linear_drag_ned_n(R[:, 2], V, CXY, CZ)
    assert np.allclose(linear, drag.drag_ned_n(R, V, CXY, CZ, 0.0), atol=1e-12)
    change = drag.drag_change_n(R, V, 1.3, CXY, CZ, CP)
    assert np.allclose(change, drag.drag_ned_n(R, 1.3 * V, CXY, CZ, CP) - full, atol=1e-12)
    # negative control: the body-frame drag is not the NED one
    assert not np.allclose(drag.body_drag_n(V, CXY, CZ, CP), full, atol=1e-3)


def test_kernels_agree_with_the_reference():
    Rt = tuple(R.reshape(9))
    assert np.allclose(drag_kernel.drag_ned(Rt, *V, CXY, CZ, CP), drag.drag_ned_n(R, V, CXY, CZ, CP),
                       rtol=0, atol=1e-12)
    assert np.array_equal(drag_kernel.body_drag(*V, CXY, CZ, CP), drag.body_drag_n(V, CXY, CZ, CP))
    f = np.array([0.3, -0.2, 0.1])
    assert np.allclose(drag_kernel.linear_drag_and_force(Rt, *V, CXY, CZ, *f),
                       drag.linear_drag_ned_n(R[:, 2], V, CXY, CZ) + f, rtol=0, atol=1e-12)
    assert np.allclose(drag_kernel.drag_change(Rt, *V, -0.4, CXY, CZ, CP),
                       drag.drag_change_n(R, V, -0.4, CXY, CZ, CP), rtol=0, atol=1e-12)


@pytest.mark.parametrize("coefficients", [(0.0, 0.0, 0.0), (CXY, CZ, CP)])
def test_plant_kernel_is_the_design_model(coefficients):
    cxy, cz, cp = coefficients
    model = QuadrotorModel(0.749, (0.0168, 0.0174, 0.0311), 9.81, (cxy, cz), cp)
    x = np.array([1.0, -2.0, -3.0, 0.3, -0.5, 1.9, 4.0, -1.0, 0.7, 0.8, -0.6, 0.2])
    u = np.array([8.1, 0.05, -0.03, 0.01])
    out = np.empty(12)
    plant_rhs(x, *u, (model.mass_kg, model.g, cxy, cz, cp, 0.0), *model.inertia_kg_m2, out)
    assert np.allclose(out, model.f(x, u), rtol=0, atol=1e-12)

    w = x[9:12]
    assert np.allclose(angular_acceleration(*model.inertia_kg_m2, *w, *u[1:]),
                       model.body_derivatives(np.zeros(3), x[6:9], w, u)[1], rtol=0, atol=1e-12)
