r"""The disturbance compensation of the nominal as a scalar kernel that numba compiles
(:func:`mavreg.accel.njit`): :func:`mavreg.control.disturbance.compensated_nominal` with
the force of :meth:`~mavreg.control.disturbance.DisturbanceEstimate.extra_force_ned`, the
maths of those two step for step.

Rotations are 9-tuples, row-major, so that nothing is allocated:
:math:`R = R_z(\psi) R_y(\theta) R_x(\phi)` (:func:`mavreg.model.rotation.rpy_to_matrix`).
With :math:`b_3 = R e_3`, :math:`v = R \bar v_b` and the extra force
:math:`d = -\delta c_{xy}(v - (b_3^T v) b_3) - \delta c_z (b_3^T v) b_3 + F`, the thrust
vector :math:`u = \bar T b_3 + d` turns the body z axis by the smallest rotation onto
:math:`u/|u|` (Rodrigues, capped at ``max_turn_rad``); the angles follow that attitude on
the nominal's branch, the body velocity is the nominal's NED velocity in the turned frame,
and the rates gain the difference of the compensated and the nominal attitudes'
finite-difference rates to the nominal ``dt_s`` ahead.
"""
from __future__ import annotations

import math

from ..accel import njit

__all__ = ["rpy_matrix", "compensate"]


@njit
def rpy_matrix(phi, theta, psi):
    """R = Rz(psi) Ry(theta) Rx(phi), row-major 9-tuple."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return (cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * st * cf,
            sp * ct, cp * cf + sp * st * sf, -cp * sf + sp * st * cf,
            -st, ct * sf, ct * cf)


@njit
def _mv(R, a, b, c):
    """R (a, b, c)."""
    return (R[0] * a + R[1] * b + R[2] * c, R[3] * a + R[4] * b + R[5] * c,
            R[6] * a + R[7] * b + R[8] * c)


@njit
def _mtv(R, a, b, c):
    """R^T (a, b, c)."""
    return (R[0] * a + R[3] * b + R[6] * c, R[1] * a + R[4] * b + R[7] * c,
            R[2] * a + R[5] * b + R[8] * c)


@njit
def _mm(A, B):
    """A B."""
    return (A[0] * B[0] + A[1] * B[3] + A[2] * B[6], A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
            A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
            A[3] * B[0] + A[4] * B[3] + A[5] * B[6], A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
            A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
            A[6] * B[0] + A[7] * B[3] + A[8] * B[6], A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
            A[6] * B[2] + A[7] * B[5] + A[8] * B[8])


@njit
def _mtm(A, B):
    """A^T B."""
    return (A[0] * B[0] + A[3] * B[3] + A[6] * B[6], A[0] * B[1] + A[3] * B[4] + A[6] * B[7],
            A[0] * B[2] + A[3] * B[5] + A[6] * B[8],
            A[1] * B[0] + A[4] * B[3] + A[7] * B[6], A[1] * B[1] + A[4] * B[4] + A[7] * B[7],
            A[1] * B[2] + A[4] * B[5] + A[7] * B[8],
            A[2] * B[0] + A[5] * B[3] + A[8] * B[6], A[2] * B[1] + A[5] * B[4] + A[8] * B[7],
            A[2] * B[2] + A[5] * B[5] + A[8] * B[8])


@njit
def wrap(a):
    """a wrapped to (-pi, pi] (:func:`mavreg.model.rotation.wrap_angle`)."""
    return math.pi - (math.pi - a) % (2.0 * math.pi)


@njit
def _extra_force(R, v0, v1, v2, dcxy, dcz, fx, fy, fz):
    """The force the design model misses at attitude R and NED velocity v (drag excess and
    constant force; ``dcxy, dcz`` the estimate less the design's drag)."""
    along = R[2] * v0 + R[5] * v1 + R[8] * v2
    return (-dcxy * (v0 - along * R[2]) - dcz * along * R[2] + fx,
            -dcxy * (v1 - along * R[5]) - dcz * along * R[5] + fy,
            -dcxy * (v2 - along * R[8]) - dcz * along * R[8] + fz)


@njit
def _turned(R, thrust_n, f0, f1, f2, max_turn_rad):
    """(R', T') of :func:`mavreg.control.disturbance._turned`."""
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
    KK = _mm(Kx, Kx)
    q = 1.0 - c
    G = (1.0 + s * Kx[0] + q * KK[0], s * Kx[1] + q * KK[1], s * Kx[2] + q * KK[2],
         s * Kx[3] + q * KK[3], 1.0 + s * Kx[4] + q * KK[4], s * Kx[5] + q * KK[5],
         s * Kx[6] + q * KK[6], s * Kx[7] + q * KK[7], 1.0 + s * Kx[8] + q * KK[8])
    R2 = _mm(G, R)
    if capped:
        T = u0 * R2[2] + u1 * R2[5] + u2 * R2[8]
    return R2, T


@njit
def _log_vee(R):
    """The rotation vector of R, angle in [0, pi] (:func:`mavreg.model.so3.log_so3`: the series
    below 1e-4 rad, the axis from the symmetric part near pi)."""
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
def compensate(xbar, thrust_n, x_ahead, thrust_ahead_n, dcxy, dcz, fx, fy, fz, dt_s, max_turn_rad):
    """Compensate the nominal ``xbar`` (12,) in place for the extra force; return the thrust.

    ``x_ahead``, ``thrust_ahead_n``: the nominal ``dt_s`` ahead (for the turn's rate);
    ``dcxy, dcz``: the estimated drag less the design's; ``fx, fy, fz``: the constant force.
    """
    R = rpy_matrix(xbar[3], xbar[4], xbar[5])
    v0, v1, v2 = _mv(R, xbar[6], xbar[7], xbar[8])
    e0, e1, e2 = _extra_force(R, v0, v1, v2, dcxy, dcz, fx, fy, fz)
    Ra = rpy_matrix(x_ahead[3], x_ahead[4], x_ahead[5])
    w0, w1, w2 = _mv(Ra, x_ahead[6], x_ahead[7], x_ahead[8])
    g0, g1, g2 = _extra_force(Ra, w0, w1, w2, dcxy, dcz, fx, fy, fz)
    R2, T = _turned(R, thrust_n, e0, e1, e2, max_turn_rad)
    Ra2, _ = _turned(Ra, thrust_ahead_n, g0, g1, g2, max_turn_rad)
    c0, c1, c2 = _log_vee(_mtm(R2, Ra2))
    n0, n1, n2 = _log_vee(_mtm(R, Ra))
    theta = -math.asin(min(max(R2[6], -1.0), 1.0))
    phi = math.atan2(R2[7], R2[8])
    psi = math.atan2(R2[3], R2[0])
    xbar[3] = xbar[3] + wrap(phi - xbar[3])
    xbar[4] = xbar[4] + wrap(theta - xbar[4])
    xbar[5] = xbar[5] + wrap(psi - xbar[5])
    xbar[6], xbar[7], xbar[8] = _mtv(R2, v0, v1, v2)
    xbar[9] = xbar[9] + (c0 - n0) / dt_s
    xbar[10] = xbar[10] + (c1 - n1) / dt_s
    xbar[11] = xbar[11] + (c2 - n2) / dt_s
    return T
