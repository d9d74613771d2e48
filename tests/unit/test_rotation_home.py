"""Rotations have one home (mavreg.model.rotation, kernels in mavreg.model.rotation_kernel):
the kernel forms agree with the numpy reference, the batch and single quaternion maps are one
formula, and the one angle wrap has its edge at (-pi, pi]."""
import math

import numpy as np

from mavreg.model import rotation as rot
from mavreg.model import rotation_kernel as rk
from mavreg.sim.truth import quats_to_matrices as truth_quats_to_matrices


def test_matrix_rpy_kernel_is_the_reference():
    for angles in ((0.3, -1.2, 2.9), (-2.5, 0.4, -0.1), (1.0, math.pi / 2, 0.5)):
        R = rot.rpy_to_matrix(*angles)
        assert np.array_equal(rk.matrix_rpy(tuple(R.reshape(9))), rot.matrix_to_rpy(R))


def test_one_quaternion_formula():
    q = np.array([[0.9, 0.1, -0.3, 0.2], [0.0, 1.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0]])
    R = rot.quats_to_matrices(q)
    assert truth_quats_to_matrices is rot.quats_to_matrices
    for qi, Ri in zip(q, R):
        assert np.array_equal(rot.quat_to_matrix(qi), Ri)
        assert np.allclose(Ri @ Ri.T, np.eye(3), atol=1e-12)
    assert np.allclose(rot.quat_to_matrix(rot.rpy_to_quat(0.2, -0.4, 1.1)), rot.rpy_to_matrix(0.2, -0.4, 1.1),
                       atol=1e-12)


def test_the_wrap_edge_is_minus_pi_open_pi_closed():
    a = np.array([math.pi, -math.pi, 3 * math.pi, 0.5, -7.0])
    w = rot.wrap_angle(a)
    assert w[0] == math.pi and w[1] == math.pi and w[2] == math.pi
    assert np.all((w > -math.pi) & (w <= math.pi))
    assert [rk.wrap(float(x)) for x in a] == list(w)
