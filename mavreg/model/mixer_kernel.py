r"""Rotor mixing (eq 34) and the allocation policies for the compiled kernels
(:func:`mavreg.accel.njit`): :mod:`mavreg.model.mixer`'s maths on scalars, M^{-1} row-major
(16,), nothing allocated but the output row. ``tests/unit/test_fastpath.py`` and
``tests/unit/test_mixer_kernel.py`` hold them to the numpy reference.
"""
from __future__ import annotations

import numpy as np

from ..accel import njit

__all__ = ["wrench", "yaw_then_lift", "torques_first"]


@njit
def wrench(arm_m, k_m, f0, f1, f2, f3):
    """(f, g1, g2, g3) of eq 34 from rotor forces f0..f3 (front, right, back, left):
    :meth:`mavreg.model.mixer.Mixer.to_wrench` written out."""
    return f0 + f1 + f2 + f3, arm_m * (f3 - f1), arm_m * (f0 - f2), k_m * (-f0 + f1 - f2 + f3)


@njit
def _split(Minv, u, r):
    """Rotor r's share of thrust, roll and pitch, and of yaw: ``(b, y)`` of eq 34 inverted."""
    return Minv[4 * r] * u[0] + Minv[4 * r + 1] * u[1] + Minv[4 * r + 2] * u[2], Minv[4 * r + 3] * u[3]


@njit
def _fill(Minv, u, beta, f):
    """f = b + beta y per rotor; returns (min f, max f)."""
    low, high = np.inf, -np.inf
    for r in range(4):
        b, y = _split(Minv, u, r)
        f[r] = b + beta * y
        low = min(low, f[r])
        high = max(high, f[r])
    return low, high


@njit
def yaw_then_lift(Minv, u, F, f):
    """:func:`mavreg.model.mixer.yaw_then_lift` of u (4,) into f (4,), Minv row-major (16,)."""
    low, _ = _fill(Minv, u, 1.0, f)
    if low >= 0.0:
        return
    beta = 1.0
    for r in range(4):
        b, y = _split(Minv, u, r)
        if b + y < 0.0 and y != 0.0:    # as mixer.yaw_then_lift: no yaw share, no limit from it
            beta = min(beta, max(b, 0.0) / -y)
    low, high = _fill(Minv, u, beta, f)
    if low < 0.0:
        lift = min(-low, max(F - high, 0.0))
        for r in range(4):
            f[r] += lift


@njit
def torques_first(Minv, u, F, f):
    """:func:`mavreg.model.mixer.torques_first` of u (4,) into f (4,), Minv row-major (16,)."""
    low, high = _fill(Minv, u, 1.0, f)
    if low >= 0.0 and high <= F:
        return
    beta = 1.0
    for r in range(4):          # a rotor out of range with the yaw's help: no yaw
        b, y = _split(Minv, u, r)
        if b + y < 0.0 and y != 0.0:
            beta = min(beta, max(b, 0.0) / -y) if y < 0.0 else 0.0
        elif b + y > F and y != 0.0:
            beta = min(beta, max(F - b, 0.0) / y) if y > 0.0 else 0.0
    low, high = _fill(Minv, u, beta, f)
    if high - low <= F:
        shift = low if low < 0.0 else (high - F if high > F else 0.0)
        for r in range(4):
            f[r] -= shift
        return
    for r in range(4):
        f[r] = (f[r] - low) * (F / (high - low))
