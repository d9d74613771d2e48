"""Attitude: roll-pitch-yaw (ZYX) rotation matrices, quaternions, angle wrapping.

R maps body (FRD) vectors to inertial (NED) vectors, R = Rz(psi) Ry(theta) Rx(phi).
This is the paper's eq 5 with its two slips fixed: entries (1,2) and (2,2) read
``-s(psi) c(phi) + c(psi) s(theta) s(phi)`` and ``c(psi) c(phi) + s(psi) s(theta) s(phi)``
(the paper prints c(theta) for c(phi) in both). Every function here works on complex
arguments too, so that the linearization can use complex-step differentiation.
"""
from __future__ import annotations

import numpy as np

__all__ = ["rpy_to_matrix", "matrix_to_rpy", "rpy_to_quat", "quat_to_matrix", "quat_to_rpy",
           "quats_to_matrices", "matrices_to_quats", "wrap_angle", "euler_rates_matrix"]


def rpy_to_matrix(phi, theta, psi) -> np.ndarray:
    """Rotation matrix R = Rz(psi) Ry(theta) Rx(phi) (body to inertial)."""
    cf, sf = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cp, sp = np.cos(psi), np.sin(psi)
    return np.array([
        [cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * st * cf],
        [sp * ct, cp * cf + sp * st * sf, -cp * sf + sp * st * cf],
        [-st, ct * sf, ct * cf],
    ])


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw of a rotation matrix (3, 3), or of a stack (..., 3, 3) giving
    (..., 3); pitch in [-pi/2, pi/2]."""
    R = np.asarray(R)
    theta = -np.arcsin(np.clip(R[..., 2, 0], -1.0, 1.0))
    phi = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    psi = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([phi, theta, psi], axis=-1)


def rpy_to_quat(phi, theta, psi) -> np.ndarray:
    """Quaternion (w, x, y, z), scalar first, of R = Rz(psi) Ry(theta) Rx(phi)."""
    cf, sf = np.cos(phi / 2), np.sin(phi / 2)
    ct, st = np.cos(theta / 2), np.sin(theta / 2)
    cp, sp = np.cos(psi / 2), np.sin(psi / 2)
    return np.array([
        cp * ct * cf + sp * st * sf,
        cp * ct * sf - sp * st * cf,
        cp * st * cf + sp * ct * sf,
        sp * ct * cf - cp * st * sf,
    ])


def quats_to_matrices(q) -> np.ndarray:
    """(N, 3, 3) rotation matrices of quaternions (N, 4), scalar first (normalized here)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a quaternion (w, x, y, z) (normalized here)."""
    return quats_to_matrices(np.asarray(q, dtype=float).reshape(1, 4))[0]


def matrices_to_quats(R) -> np.ndarray:
    """Unit quaternions (N, 4), (w, x, y, z) with w >= 0, of rotation matrices (N, 3, 3).

    Shepperd's method: each row is computed from the largest of the four squared components,
    so it stays accurate at any angle (a loop's inverted top included).
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = np.trace(R, axis1=1, axis2=2)
    diag = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    pick = np.argmax(diag, axis=1)
    q = np.empty((R.shape[0], 4))
    for k in range(4):
        m = pick == k
        if not np.any(m):
            continue
        r = R[m]
        if k == 0:
            d = 2.0 * np.sqrt(1.0 + tr[m])
            rows = [d / 4, (r[:, 2, 1] - r[:, 1, 2]) / d, (r[:, 0, 2] - r[:, 2, 0]) / d,
                    (r[:, 1, 0] - r[:, 0, 1]) / d]
        else:
            i, j, l = (k - 1, k % 3, (k + 1) % 3)
            d = 2.0 * np.sqrt(1.0 + r[:, i, i] - r[:, j, j] - r[:, l, l])
            comp = [None] * 4
            comp[0] = (r[:, l, j] - r[:, j, l]) / d
            comp[1 + i] = d / 4
            comp[1 + j] = (r[:, j, i] + r[:, i, j]) / d
            comp[1 + l] = (r[:, l, i] + r[:, i, l]) / d
            rows = comp
        q[m] = np.stack(rows, axis=1)
    q *= np.where(q[:, :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def quat_to_rpy(q) -> np.ndarray:
    """Roll, pitch, yaw of a unit quaternion (w, x, y, z)."""
    return matrix_to_rpy(quat_to_matrix(q))


def wrap_angle(a):
    """Wrap angles to (-pi, pi]: the one wrap of mavreg (the kernels' is
    :func:`mavreg.model.rotation_kernel.wrap`, the same formula)."""
    return np.pi - np.mod(np.pi - a, 2 * np.pi)


def euler_rates_matrix(phi, theta) -> np.ndarray:
    """W such that (phi, theta, psi)' = W (p, q, r): paper eqs 9-11."""
    cf, sf = np.cos(phi), np.sin(phi)
    ct, tt = np.cos(theta), np.tan(theta)
    one, zero = np.ones_like(cf), np.zeros_like(cf)
    return np.array([
        [one, sf * tt, cf * tt],
        [zero, cf, -sf],
        [zero, sf / ct, cf / ct],
    ])
