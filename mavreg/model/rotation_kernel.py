r"""Rotations as 9-tuples (row-major) for the compiled kernels (:func:`mavreg.accel.njit`):
nothing is allocated, and numba keeps them in registers.

The same maths as :func:`mavreg.model.rotation.rpy_to_matrix` (:math:`R = R_z(\psi) R_y(\theta)
R_x(\phi)`), :func:`~mavreg.model.rotation.matrix_to_rpy`, :func:`~mavreg.model.rotation.wrap_angle`, :func:`mavreg.model.so3.log_so3` (the
series below 1e-4 rad, the axis from the symmetric part near pi) and
:func:`mavreg.control.controllers.attitude_table.rodrigues` (Exp of a rotation vector, the series below
1e-4 rad), operation for operation where it matters for rounding.
"""
from __future__ import annotations

import math

from ..accel import njit

__all__ = ["rpy_matrix", "matrix_rpy", "mv", "mtv", "mm", "mtm", "wrap", "log_vee", "rodrigues"]


@njit
def rpy_matrix(phi, theta, psi):
    """R = Rz(psi) Ry(theta) Rx(phi)."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return (cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * st * cf,
            sp * ct, cp * cf + sp * st * sf, -cp * sf + sp * st * cf,
            -st, ct * sf, ct * cf)


@njit
def matrix_rpy(R):
    """Roll, pitch, yaw of R (:func:`mavreg.model.rotation.matrix_to_rpy`), pitch in
    [-pi/2, pi/2]."""
    return (math.atan2(R[7], R[8]), -math.asin(min(max(R[6], -1.0), 1.0)), math.atan2(R[3], R[0]))


@njit
def mv(R, a, b, c):
    """R (a, b, c)."""
    return (R[0] * a + R[1] * b + R[2] * c, R[3] * a + R[4] * b + R[5] * c,
            R[6] * a + R[7] * b + R[8] * c)


@njit
def mtv(R, a, b, c):
    """R^T (a, b, c)."""
    return (R[0] * a + R[3] * b + R[6] * c, R[1] * a + R[4] * b + R[7] * c,
            R[2] * a + R[5] * b + R[8] * c)


@njit
def mm(A, B):
    """A B."""
    return (A[0] * B[0] + A[1] * B[3] + A[2] * B[6], A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
            A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
            A[3] * B[0] + A[4] * B[3] + A[5] * B[6], A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
            A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
            A[6] * B[0] + A[7] * B[3] + A[8] * B[6], A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
            A[6] * B[2] + A[7] * B[5] + A[8] * B[8])


@njit
def mtm(A, B):
    """A^T B."""
    return (A[0] * B[0] + A[3] * B[3] + A[6] * B[6], A[0] * B[1] + A[3] * B[4] + A[6] * B[7],
            A[0] * B[2] + A[3] * B[5] + A[6] * B[8],
            A[1] * B[0] + A[4] * B[3] + A[7] * B[6], A[1] * B[1] + A[4] * B[4] + A[7] * B[7],
            A[1] * B[2] + A[4] * B[5] + A[7] * B[8],
            A[2] * B[0] + A[5] * B[3] + A[8] * B[6], A[2] * B[1] + A[5] * B[4] + A[8] * B[7],
            A[2] * B[2] + A[5] * B[5] + A[8] * B[8])


@njit
def wrap(a):
    """a wrapped to (-pi, pi]."""
    return math.pi - (math.pi - a) % (2.0 * math.pi)


@njit
def log_vee(R):
    """The rotation vector of R, angle in [0, pi]."""
    w0 = 0.5 * (R[7] - R[5])
    w1 = 0.5 * (R[2] - R[6])
    w2 = 0.5 * (R[3] - R[1])
    sin_t = math.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    cos_t = min(max((R[0] + R[4] + R[8] - 1.0) / 2.0, -1.0), 1.0)
    t = math.atan2(sin_t, cos_t)
    if cos_t < -0.9:
        q = 1.0 - cos_t
        k = 0
        for j in (4, 8):
            if R[j] > R[4 * k]:
                k = j // 4
        b0 = ((R[3 * k] + R[k]) / 2.0 - (cos_t if k == 0 else 0.0)) / q
        b1 = ((R[3 * k + 1] + R[3 + k]) / 2.0 - (cos_t if k == 1 else 0.0)) / q
        b2 = ((R[3 * k + 2] + R[6 + k]) / 2.0 - (cos_t if k == 2 else 0.0)) / q
        n = math.sqrt((b0, b1, b2)[k])
        sign = -1.0 if b0 * w0 + b1 * w1 + b2 * w2 < 0.0 else 1.0
        return sign * t * b0 / n, sign * t * b1 / n, sign * t * b2 / n
    g = 1.0 + sin_t * sin_t / 6.0 if sin_t < 1e-4 else t / sin_t
    return g * w0, g * w1, g * w2


@njit
def rodrigues(x, y, z):
    """Exp of the rotation vector (x, y, z)."""
    t2 = x * x + y * y + z * z
    if t2 < 1e-8:
        s, c = 1.0 - t2 / 6.0 + t2 * t2 / 120.0, 0.5 - t2 / 24.0 + t2 * t2 / 720.0
    else:
        th = math.sqrt(t2)
        s, c = math.sin(th) / th, (1.0 - math.cos(th)) / t2
    return (1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y,
            c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x,
            c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y))
