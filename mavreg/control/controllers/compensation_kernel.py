r"""The disturbance compensation of the nominal as a scalar kernel that numba compiles
(:func:`mavreg.accel.njit`): :func:`mavreg.control.estimation.disturbance.compensate` with the force of
:meth:`~mavreg.control.estimation.disturbance.DisturbanceEstimate.extra_force_ned`, the maths of those
two step for step.

Rotations are 9-tuples, row-major (:mod:`mavreg.model.rotation_kernel`). With the nominal
attitude R, :math:`b_3 = R e_3`, :math:`v = R \bar v_b` and the extra force
:math:`d = -\delta c_{xy}(v - (b_3^T v) b_3) - \delta c_z (b_3^T v) b_3 + F`
(``extra_force``: :func:`mavreg.model.drag_kernel.linear_drag_and_force`), the thrust
vector :math:`u = \bar T b_3 + d` turns the body z axis by the smallest rotation onto
:math:`u/|u|` (Rodrigues, capped at ``max_turn_rad``); the angles follow that attitude on
the nominal's branch, the body velocity is the nominal's NED velocity in the turned frame,
and the rates gain the difference of the compensated and the nominal attitudes'
finite-difference rates to the nominal ``dt_s`` ahead.
"""
from __future__ import annotations

import math

from ...accel import njit
from ...model.drag_kernel import linear_drag_and_force as extra_force
from ...model.rotation_kernel import log_vee, matrix_rpy, mm, mtm, mtv, mv, wrap

__all__ = ["compensate", "extra_force"]


@njit
def _turned(R, thrust_n, f0, f1, f2, max_turn_rad):
    """(R', T') of :func:`mavreg.control.estimation.disturbance._turned`."""
    b0, b1, b2 = R[2], R[5], R[8]
    u0 = thrust_n * b0 + f0
    u1 = thrust_n * b1 + f1
    u2 = thrust_n * b2 + f2
    T = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    if T < 1e-9:
        return R, thrust_n
    n0, n1, n2 = u0 / T, u1 / T, u2 / T
    a0 = b1 * n2 - b2 * n1
    a1 = b2 * n0 - b0 * n2
    a2 = b0 * n1 - b1 * n0
    s = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    c = b0 * n0 + b1 * n1 + b2 * n2
    if s <= 1e-12:
        return R, T
    k0, k1, k2 = a0 / s, a1 / s, a2 / s
    capped = math.atan2(s, c) > max_turn_rad
    if capped:
        s, c = math.sin(max_turn_rad), math.cos(max_turn_rad)
    Kx = (0.0, -k2, k1, k2, 0.0, -k0, -k1, k0, 0.0)
    KK = mm(Kx, Kx)
    q = 1.0 - c
    G = (1.0 + s * Kx[0] + q * KK[0], s * Kx[1] + q * KK[1], s * Kx[2] + q * KK[2],
         s * Kx[3] + q * KK[3], 1.0 + s * Kx[4] + q * KK[4], s * Kx[5] + q * KK[5],
         s * Kx[6] + q * KK[6], s * Kx[7] + q * KK[7], 1.0 + s * Kx[8] + q * KK[8])
    R2 = mm(G, R)
    if capped:
        T = u0 * R2[2] + u1 * R2[5] + u2 * R2[8]
    return R2, T


@njit
def compensate(xbar, R, thrust_n, f0, f1, f2, R_ahead, thrust_ahead_n, g0, g1, g2, dt_s, max_turn_rad):
    """Compensate the nominal ``xbar`` (12,), attitude ``R``, in place for the force
    (f0, f1, f2); return ``(thrust, R')``, R' the turned attitude
    (:func:`mavreg.control.estimation.disturbance.compensate`).

    ``R_ahead``, ``thrust_ahead_n``, (g0, g1, g2): the nominal's attitude, thrust and force
    ``dt_s`` ahead, for the turn's rate (``dt_s`` <= 0: the rates are kept).
    """
    v0, v1, v2 = mv(R, xbar[6], xbar[7], xbar[8])
    R2, T = _turned(R, thrust_n, f0, f1, f2, max_turn_rad)
    phi, theta, psi = matrix_rpy(R2)
    xbar[3] = xbar[3] + wrap(phi - xbar[3])
    xbar[4] = xbar[4] + wrap(theta - xbar[4])
    xbar[5] = xbar[5] + wrap(psi - xbar[5])
    xbar[6], xbar[7], xbar[8] = mtv(R2, v0, v1, v2)
    if dt_s > 0.0:
        Ra2, _ = _turned(R_ahead, thrust_ahead_n, g0, g1, g2, max_turn_rad)
        c0, c1, c2 = log_vee(mtm(R2, Ra2))
        n0, n1, n2 = log_vee(mtm(R, R_ahead))
        xbar[9] = xbar[9] + (c0 - n0) / dt_s
        xbar[10] = xbar[10] + (c1 - n1) / dt_s
        xbar[11] = xbar[11] + (c2 - n2) / dt_s
    return T, R2
