"""The torque-bias observer's kernels (:mod:`mavreg.control.estimation.torque_bias`): the bias at
a collective, the allocation less the bias, and one measurement of the Kalman filter.

Its numpy reference is :func:`~mavreg.control.estimation.torque_bias.allocated_less_bias` for
the allocation; the filter's reference is this kernel run as plain Python (``MAVREG_PURE=1``).
"""
from __future__ import annotations

import math

import numpy as np

from ...accel import njit
from ...model.mixer_kernel import torques_first, yaw_then_lift

__all__ = ["update", "rotor_wrench", "allocate_less_bias", "bias_n_m", "THETA", "APPLIED", "Q_PER_S", "RATE",
           "LO", "HI", "ROWS", "GATE_CHI2", "SKIPPED", "REJECTED", "UPDATED", "PASSES", "THRUST_TOL_N"]

THETA, APPLIED, Q_PER_S, RATE, LO, HI = range(6)
ROWS = 6
"""Rows of ``kf`` (ROWS, 6), each over (t0 x, y, z, t1 x, y, z): the estimate and its
rate-limited follower (updated in place), then the constants: the random walks' intensities,
the follower's rate bounds, the estimate's bounds."""
GATE_CHI2 = 36.0
"""As the force part's: 6 sigma (Mahalanobis, here over the three axes)."""
SKIPPED, REJECTED, UPDATED = 0, 1, 2
PASSES = 4
"""Allocations at most per command (:func:`allocate_less_bias`): where the allocation moves the
collective, each pass shrinks the bias's error by about t1 dT/dtau (a few per cent on the
MK-Quadro): at the barrel roll's exit four leave 3e-6 N m of its 0.04 N m."""
THRUST_TOL_N = 1e-6


@njit
def bias_n_m(tb, thrust_n, axis):
    """The torque bias ``t0 + t1 T`` about ``axis`` (0, 1, 2) of ``tb`` (6,) at collective ``thrust_n``."""
    return tb[axis] + tb[3 + axis] * thrust_n


@njit
def rotor_wrench(u, tb, thrust_n, out):
    """``out`` (4,) = the wrench ``u`` (4,) the rotors must give when the airframe adds the
    torque bias ``tb`` (6,) at the collective ``thrust_n``: the torques less the bias."""
    out[0] = u[0]
    for a in range(3):
        out[1 + a] = u[1 + a] - bias_n_m(tb, thrust_n, a)


@njit
def allocate_less_bias(minv, u, fmax, tb, torques_first_alloc, f):
    """Rotor forces ``f`` (4,) for the wrench ``u`` (4,) on an airframe that adds the torque
    bias ``tb`` (6,): the allocation (:func:`~mavreg.model.mixer_kernel.torques_first`, else
    :func:`~mavreg.model.mixer_kernel.yaw_then_lift`; ``minv`` row-major) of ``u`` less the
    bias at the collective the rotors give. That is ``u[0]`` unless the allocation moves the
    collective (a rotor would pull: all four are lifted; one would pass ``fmax``): then the
    bias is taken again at the collective allocated (a negative collective asked for at the
    barrel roll's exit is flown at a positive one)."""
    want = np.empty(4)
    thrust = max(u[0], 0.0)
    for attempt in range(PASSES):
        rotor_wrench(u, tb, thrust, want)
        if torques_first_alloc:
            torques_first(minv, want, fmax, f)
        else:
            yaw_then_lift(minv, want, fmax, f)
        given = f[0] + f[1] + f[2] + f[3]
        if abs(given - thrust) <= THRUST_TOL_N:
            break
        thrust = given


@njit
def update(kf, P, dt, inv_j, r, thrust, y0, y1, y2):
    """One measurement: rate innovation ``(y0, y1, y2)`` (rad/s) over ``dt`` with the mean
    collective ``thrust`` (N); ``inv_j`` (3,) the design's 1/J per axis, ``r`` the measurement
    variance. ``P`` (3, 3): per axis the covariance's (00, 01, 11). Returns :data:`SKIPPED`
    (a non-finite innovation), :data:`REJECTED` (the gate) or :data:`UPDATED`."""
    if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2) and math.isfinite(thrust)):
        return SKIPPED
    ys = (y0, y1, y2)
    chi2 = 0.0
    for a in range(3):
        P[a, 0] += kf[Q_PER_S, a] * dt
        P[a, 2] += kf[Q_PER_S, 3 + a] * dt
        g = dt * inv_j[a]
        h0, h1 = g, g * thrust
        s = h0 * h0 * P[a, 0] + 2.0 * h0 * h1 * P[a, 1] + h1 * h1 * P[a, 2] + r
        chi2 += ys[a] * ys[a] / s
    if chi2 > GATE_CHI2:
        return REJECTED
    for a in range(3):
        g = dt * inv_j[a]
        h0, h1 = g, g * thrust
        p00, p01, p11 = P[a, 0], P[a, 1], P[a, 2]
        ph0 = p00 * h0 + p01 * h1               # P H^T
        ph1 = p01 * h0 + p11 * h1
        s = h0 * ph0 + h1 * ph1 + r
        k0, k1 = ph0 / s, ph1 / s
        kf[THETA, a] = min(max(kf[THETA, a] + k0 * ys[a], kf[LO, a]), kf[HI, a])
        kf[THETA, 3 + a] = min(max(kf[THETA, 3 + a] + k1 * ys[a], kf[LO, 3 + a]), kf[HI, 3 + a])
        # Joseph form: (I - K H) P (I - K H)^T + r K K^T
        a00, a01 = 1.0 - k0 * h0, -k0 * h1
        a10, a11 = -k1 * h0, 1.0 - k1 * h1
        b00, b01 = a00 * p00 + a01 * p01, a00 * p01 + a01 * p11
        b10, b11 = a10 * p00 + a11 * p01, a10 * p01 + a11 * p11
        P[a, 0] = b00 * a00 + b01 * a01 + r * k0 * k0
        P[a, 1] = b00 * a10 + b01 * a11 + r * k0 * k1
        P[a, 2] = b10 * a10 + b11 * a11 + r * k1 * k1
    for j in range(6):
        step = kf[RATE, j] * dt
        d = kf[THETA, j] - kf[APPLIED, j]
        kf[APPLIED, j] += min(max(d, -step), step)
    return UPDATED
