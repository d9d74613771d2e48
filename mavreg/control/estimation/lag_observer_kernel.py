r"""The rotor-lag observer's kernels (:mod:`mavreg.control.estimation.lag_observer`): the lag
filter's sensitivity advanced over a sample interval, and one measurement of the scalar
Kalman filter on the rotors' time constant. The reference is this kernel run as plain Python
(``MAVREG_PURE=1``); the maths is in the observer's module docstring.
"""
from __future__ import annotations

import math

import numpy as np

from ...accel import njit

__all__ = ["update", "advance_sensitivity", "TAU", "APPLIED", "P", "G0", "SIZE", "GATE_CHI2",
           "SKIPPED", "REJECTED", "UPDATED", "PROPAGATED"]

TAU, APPLIED, P = 0, 1, 2
G0 = 3
"""``state`` (SIZE,): the estimate (s), its follower (s), its variance (s^2), then the
sensitivity :math:`M_\\tau g` per body axis (N m per second of time constant)."""
SIZE = 6
GATE_CHI2 = 36.0
"""As the force and torque parts': 6 sigma (Mahalanobis, over the three axes)."""
SKIPPED, PROPAGATED, REJECTED, UPDATED = 0, 1, 2, 3


@njit
def advance_sensitivity(state, h, inv_j, dtorque, phi):
    r"""Over one sample interval ``h`` (s) with the model's torque change ``dtorque`` (3,)
    (N m, physical; its slope held over the interval): ``phi`` (3,) = the body-rate change per
    second of time constant, :math:`J^{-1}\int M_\tau g\,dt`, exact for that slope; and the
    sensitivity in ``state`` advanced to the interval's end."""
    tau = state[TAU]
    e = math.exp(-h / tau) if tau > 0.0 else 0.0
    w = tau * (1.0 - e)                  # the integral of e^{-t/tau} over the interval
    for a in range(3):
        slope = dtorque[a] / h
        g = state[G0 + a]
        phi[a] = inv_j[a] * (w * g - slope * (h - w))
        state[G0 + a] = g * e - slope * (1.0 - e)


@njit
def update(state, h, inv_j, dtorque, y, learn, q_per_s, r, lo, hi, rate):
    """One sample interval ``h`` (s): the model's torque change over it ``dtorque`` (3,)
    (N m, physical), the body-rate innovation ``y`` (3,) (rad/s), ``inv_j`` (3,) the design's
    1/J. The sensitivity always advances; the estimate learns only if ``learn``. ``q_per_s``
    the random walk's intensity, ``r`` the innovation's variance per axis, ``lo``/``hi`` the
    bounds, ``rate`` the follower's (s/s). Returns :data:`SKIPPED` (non-finite input; the
    sensitivity restarts), :data:`PROPAGATED` (not learned), :data:`REJECTED` (the gate) or
    :data:`UPDATED`."""
    if not (h > 0.0 and math.isfinite(h)):
        return SKIPPED
    for a in range(3):
        if not (math.isfinite(dtorque[a]) and math.isfinite(y[a])):
            for b in range(3):
                state[G0 + b] = 0.0
            return SKIPPED
    phi = np.empty(3)
    advance_sensitivity(state, h, inv_j, dtorque, phi)
    state[P] += q_per_s * h
    if not learn:
        return PROPAGATED
    pv = state[P]
    pp = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    py = phi[0] * y[0] + phi[1] * y[1] + phi[2] * y[2]
    yy = y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
    s = r + pv * pp
    if (yy - pv * py * py / s) / r > GATE_CHI2:      # y^T (P phi phi^T + r I)^-1 y
        return REJECTED
    state[TAU] = min(max(state[TAU] + pv * py / s, lo), hi)
    state[P] = pv * r / s
    step = rate * h
    d = state[TAU] - state[APPLIED]
    state[APPLIED] += min(max(d, -step), step)
    return UPDATED
