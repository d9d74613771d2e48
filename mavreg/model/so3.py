r"""Rotations as matrices, with the exponential and logarithm maps of SO(3).

The attitude error of the singularity-free regulator is the rotation vector of the body
relative to the nominal, expressed in the nominal body frame:

.. math::
    R = \bar R \,\mathrm{Exp}(e), \qquad e = \mathrm{Log}(\bar R^T R)^\vee ,

defined for every attitude (|e| < pi), where roll, pitch and yaw are singular at pitch
+-90 deg. Its kinematics follow from :math:`\dot R = R\hat\omega` and
:math:`\dot{\bar R} = \bar R\hat{\bar\omega}`:

.. math::
    \dot e = J_r^{-1}(e)\,\big(\omega - \mathrm{Exp}(e)^T \bar\omega\big),

with :math:`J_r` the right Jacobian of SO(3). Every function takes a single vector or a
stack (..., 3) and works on complex arguments (for complex-step linearization): the
closed forms switch to their Taylor series below a small angle, where the complex step's
tiny perturbations fall.
"""
from __future__ import annotations

import numpy as np

__all__ = ["hat", "vee", "exp_so3", "log_so3", "right_jacobian_inv", "attitude_error", "rotation_angle_deg",
           "project_to_so3"]

_SMALL = 1e-4
"""Below this angle (rad) the closed forms are replaced by their series (error < 1e-17)."""


def hat(v) -> np.ndarray:
    """Skew matrix of v (..., 3): hat(a) @ b = a x b."""
    v = np.asarray(v)
    z = np.zeros_like(v[..., 0])
    return np.stack([np.stack([z, -v[..., 2], v[..., 1]], -1),
                     np.stack([v[..., 2], z, -v[..., 0]], -1),
                     np.stack([-v[..., 1], v[..., 0], z], -1)], -2)


def vee(M) -> np.ndarray:
    """The vector of the skew part of M (..., 3, 3)."""
    M = np.asarray(M)
    return 0.5 * np.stack([M[..., 2, 1] - M[..., 1, 2], M[..., 0, 2] - M[..., 2, 0],
                           M[..., 1, 0] - M[..., 0, 1]], -1)


def _angle2(v):
    return np.sum(v * v, axis=-1)          # theta^2, complex-safe (no abs)


def _coefficients(t2):
    """sin(t)/t, (1 - cos t)/t^2 and (1 - t sin t / (2 (1 - cos t)))/t^2 of t = sqrt(t2)."""
    small = np.real(t2) < _SMALL ** 2
    t2s = np.where(small, 1.0, t2)
    t = np.sqrt(t2s)
    a = np.where(small, 1 - t2 / 6 + t2 * t2 / 120, np.sin(t) / t)
    b = np.where(small, 0.5 - t2 / 24 + t2 * t2 / 720, (1 - np.cos(t)) / t2s)
    c = np.where(small, 1 / 12 + t2 / 720 + t2 * t2 / 30240,
                 (1 - t * np.sin(t) / (2 * (1 - np.cos(t)))) / t2s)
    return a, b, c


def exp_so3(v) -> np.ndarray:
    """Rodrigues: Exp(v) = I + sin(t)/t hat(v) + (1 - cos t)/t^2 hat(v)^2, t = |v|."""
    v = np.asarray(v)
    a, b, _ = _coefficients(_angle2(v))
    V = hat(v)
    return np.eye(3) + a[..., None, None] * V + b[..., None, None] * (V @ V)


def log_so3(R) -> np.ndarray:
    """The rotation vector of R (..., 3, 3), angle in [0, pi]; real R only.

    Near pi, where sin(t) vanishes, the axis comes from the symmetric part of R,
    ``(R + R^T)/2 = cos t I + (1 - cos t) a a^T``, its sign from the skew part.
    """
    R = np.asarray(R, dtype=float)
    w = vee(R)                                            # sin(t) a
    sin_t = np.linalg.norm(w, axis=-1)
    cos_t = np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1.0, 1.0)
    t = np.arctan2(sin_t, cos_t)
    small = sin_t < _SMALL
    out = np.where(small, 1 + sin_t ** 2 / 6, t / np.where(small, 1.0, sin_t))[..., None] * w
    near_pi = cos_t < -0.9
    if np.any(near_pi):
        Rn, tn, wn = R[near_pi], t[near_pi], w[near_pi]
        B = ((Rn + np.swapaxes(Rn, -1, -2)) / 2 - cos_t[near_pi][:, None, None] * np.eye(3)) \
            / (1 - cos_t[near_pi])[:, None, None]        # a a^T
        rows = np.arange(len(tn))
        k = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        axis = B[rows, k] / np.sqrt(B[rows, k, k])[:, None]
        sign = np.where(np.sum(axis * wn, axis=-1) < 0, -1.0, 1.0)
        out[near_pi] = (sign * tn)[:, None] * axis
    return out


def right_jacobian_inv(v) -> np.ndarray:
    """J_r^{-1}(v) = I + hat(v)/2 + c hat(v)^2, c = (1 - t sin t / (2 (1 - cos t)))/t^2."""
    v = np.asarray(v)
    _, _, c = _coefficients(_angle2(v))
    V = hat(v)
    return np.eye(3) + 0.5 * V + c[..., None, None] * (V @ V)


def attitude_error(R_nominal, R) -> np.ndarray:
    """e = Log(R_nominal^T R), the body's rotation from the nominal in the nominal's frame."""
    return log_so3(np.swapaxes(np.asarray(R_nominal), -1, -2) @ np.asarray(R))


def rotation_angle_deg(R_nominal, R) -> np.ndarray:
    """The angle (deg) of the rotation from ``R_nominal`` to ``R`` (..., 3, 3):
    :math:`\\arccos((\\mathrm{tr}(\\bar R^T R) - 1)/2)`, the cosine clipped to [-1, 1]."""
    c = (np.einsum("...ij,...ij->...", np.asarray(R_nominal), np.asarray(R)) - 1.0) / 2.0
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def project_to_so3(M) -> np.ndarray:
    """The rotation nearest to M (..., 3, 3) in the Frobenius norm (polar decomposition)."""
    u, _, vt = np.linalg.svd(np.asarray(M, dtype=float))
    d = np.sign(np.linalg.det(u @ vt))
    u[..., :, 2] *= d[..., None]
    return u @ vt
