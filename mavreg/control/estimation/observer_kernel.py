r"""One measurement of :class:`mavreg.control.estimation.disturbance.DisturbanceObserver`, one kernel.

The Kalman filter on :math:`\theta = (c_{xy}, c_z, F_n, F_e, F_d, k)` takes one velocity
innovation per sample the daemon receives. In numpy its update is some forty calls on 3x3
and 6x6 arrays (about 60 us); here it is loops on plain floats, compiled by numba
(:func:`mavreg.accel.njit`): the same steps in the same order,

.. math::
    P \mathrel{+}= \mathrm{diag}(q)\,h,\quad H = \tfrac{h}{m}\Phi,\quad
    S = H P H^T + r I,\quad y^T S^{-1} y > 36 \Rightarrow \text{refused},

    K = P H^T S^{-1},\quad \theta \leftarrow \mathrm{clip}(\theta + K y),\quad
    P \leftarrow (I - K H) P (I - K H)^T + r K K^T,

with :math:`S^{-1}` from its Cholesky factor (S is symmetric positive definite) where
numpy's ``solve`` pivots an LU factor: the two agree to rounding
(``tests/unit/test_disturbance_kernel.py``). The numpy update stays the reference, used
where numba is not (or with ``MAVREG_PURE=1``).

Layout of ``kf`` (8, 6): rows :data:`THETA`, :data:`APPLIED` (the estimate and its
rate-limited follower, updated in place), then the constants :data:`Q_PER_S` (the random
walks' intensities), :data:`RATE` (the follower's rate bounds), :data:`LO`, :data:`HI` (the
estimate's bounds). ``P`` (6, 6) is updated in place.
"""
from __future__ import annotations

import math

import numpy as np

from ...accel import njit

__all__ = ["update", "THETA", "APPLIED", "Q_PER_S", "RATE", "LO", "HI", "ROWS",
           "SKIPPED", "REJECTED", "UPDATED"]

THETA, APPLIED, Q_PER_S, RATE, LO, HI = range(6)
ROWS = 8
SKIPPED, REJECTED, UPDATED = 0, 1, 2
GATE_CHI2 = 36.0


@njit
def _matmul_into(A, B, out, transpose_b):
    """``out = A B`` (or ``A B^T`` with ``transpose_b``) by loops, for the small matrices here."""
    n, m = out.shape
    inner = A.shape[1]
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for k in range(inner):
                acc += A[i, k] * (B[j, k] if transpose_b else B[k, j])
            out[i, j] = acc


@njit
def _cholesky_solve3(l00, l10, l20, l11, l21, l22, c0, c1, c2):
    """``x = S^-1 c`` for ``S = L L^T``, L lower triangular (3, 3): forward, then back
    substitution."""
    w0 = c0 / l00
    w1 = (c1 - l10 * w0) / l11
    w2 = (c2 - l20 * w0 - l21 * w1) / l22
    x2 = w2 / l22
    x1 = (w1 - l21 * x2) / l11
    return (w0 - l10 * x1 - l20 * x2) / l00, x1, x2


@njit
def update(kf, P, dt, mass, r, min_speed, max_axial_speed, R, vx, vy, vz, thrust, y0, y1, y2, xy_scale):
    """One measurement (see the module docstring): attitude ``R`` (3, 3), velocity
    ``(vx, vy, vz)`` NED and commanded thrust ``thrust`` over the interval ``dt``, innovation
    ``(y0, y1, y2)``. The drag columns are 0 below the speed ``min_speed``, the thrust scale's
    above the axial speed ``max_axial_speed``; ``xy_scale`` multiplies the rotor-plane drag's
    column (its thrust dependence, :func:`mavreg.model.drag_kernel.rotor_plane_scale`). Returns :data:`SKIPPED` (a non-finite innovation), :data:`REJECTED`
    (the gate) or :data:`UPDATED`."""
    if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2)):
        return SKIPPED
    for i in range(6):
        P[i, i] += kf[Q_PER_S, i] * dt
    bx, by, bz = R[0, 2], R[1, 2], R[2, 2]
    along = bx * vx + by * vy + bz * vz
    g = dt / mass
    H = np.zeros((3, 6))               # (dt / m) Phi; columns left 0 where unobservable
    v = (vx, vy, vz)
    b = (bx, by, bz)
    learn_drag = math.sqrt(vx * vx + vy * vy + vz * vz) >= min_speed
    learn_scale = abs(along) <= max_axial_speed
    for a in range(3):
        if learn_drag:
            H[a, 0] = -(v[a] - along * b[a]) * g * xy_scale
            H[a, 1] = -along * b[a] * g
        H[a, 2 + a] = g
        if learn_scale:
            H[a, 5] = -thrust * b[a] * g
    HP = np.empty((3, 6))
    _matmul_into(H, P, HP, False)
    # S = H P H^T + r I, then its Cholesky factor L
    S = np.empty((3, 3))
    for a in range(3):
        for c in range(3):
            acc = 0.0
            for k in range(6):
                acc += HP[a, k] * H[c, k]
            S[a, c] = acc + (r if a == c else 0.0)
    l00 = math.sqrt(S[0, 0])
    l10 = S[1, 0] / l00
    l20 = S[2, 0] / l00
    l11 = math.sqrt(S[1, 1] - l10 * l10)
    l21 = (S[2, 1] - l20 * l10) / l11
    l22 = math.sqrt(S[2, 2] - l20 * l20 - l21 * l21)
    # z = S^-1 y (forward, then back substitution)
    z0, z1, z2 = _cholesky_solve3(l00, l10, l20, l11, l21, l22, y0, y1, y2)
    if y0 * z0 + y1 * z1 + y2 * z2 > GATE_CHI2:
        return REJECTED
    # K = (S^-1 H P)^T (6, 3), column by column of HP
    K = np.empty((6, 3))
    for j in range(6):
        K[j, 0], K[j, 1], K[j, 2] = _cholesky_solve3(l00, l10, l20, l11, l21, l22, HP[0, j], HP[1, j], HP[2, j])
    for i in range(6):
        th = kf[THETA, i] + (K[i, 0] * y0 + K[i, 1] * y1 + K[i, 2] * y2)
        kf[THETA, i] = min(max(th, kf[LO, i]), kf[HI, i])
    # A = I - K H; P <- A P A^T + r K K^T (Joseph form)
    A = np.empty((6, 6))
    for i in range(6):
        for j in range(6):
            A[i, j] = (1.0 if i == j else 0.0) - (K[i, 0] * H[0, j] + K[i, 1] * H[1, j] + K[i, 2] * H[2, j])
    AP = np.empty((6, 6))
    _matmul_into(A, P, AP, False)
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(6):
                acc += AP[i, k] * A[j, k]
            P[i, j] = acc + r * (K[i, 0] * K[j, 0] + K[i, 1] * K[j, 1] + K[i, 2] * K[j, 2])
    for i in range(6):
        step = kf[RATE, i] * dt
        d = kf[THETA, i] - kf[APPLIED, i]
        kf[APPLIED, i] += min(max(d, -step), step)
    return UPDATED
