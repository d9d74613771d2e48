r"""The speed governor and the re-timing of the nominal as scalar kernels that numba compiles
(:func:`mavreg.accel.njit`): :class:`mavreg.control.controllers.governor.SpeedGovernor` (its
:meth:`~mavreg.control.controllers.governor.SpeedGovernor.reference`),
:func:`~mavreg.control.controllers.governor.retiming_force`, step for
step (the drag change is :func:`mavreg.model.drag_kernel.drag_change`) (docs/governor.md has the maths).

The governor's tables are three columns of the step kernel's table, from column ``c``: the
target speed :math:`v_t`, its :math:`v_t v_t'` and the profile's :math:`\bar v \bar v'`; the
profile :math:`\bar v` is the table's speed column. They are read as ``numpy.interp`` reads
them (the same formula, so that the governor's comparisons of speeds decide alike). Its state
is five slots of the step's state vector from ``k``: 1.0 once it holds a governed speed, the
speed :math:`v_g`, the arc length it was reached at, the fed-forward acceleration's excess
over the profile's and that excess's rate.
"""
from __future__ import annotations

import math

import numpy as np

from ...accel import njit

__all__ = ["interp", "governed_reference", "retiming_force", "G_TARGET", "G_TARGET_ACCEL",
           "G_PROFILE_ACCEL", "GOVERNOR_COLUMNS", "ON_TARGET_M_S"]

G_TARGET, G_TARGET_ACCEL, G_PROFILE_ACCEL = 0, 1, 2
"""Offsets of the governor's columns."""
GOVERNOR_COLUMNS = 3
ON_TARGET_M_S = 0.01
"""As :data:`mavreg.control.controllers.governor._ON_TARGET_M_S`."""
AHEAD_S = 0.02
"""As :data:`mavreg.control.controllers.step_kernel.COMPENSATION_DT_S` (imported from here would be circular)."""


@njit
def interp(x, xp, table, col):
    """``numpy.interp(x, xp, table[:, col])`` for a scalar x (clamped to the ends)."""
    n = xp.shape[0]
    if x > xp[n - 1]:
        return table[n - 1, col]
    if x < xp[0]:
        return table[0, col]
    j = np.searchsorted(xp, x, side="right") - 1
    if j == n - 1 or xp[j] == x:
        return table[j, col]
    lo, hi = table[j, col], table[j + 1, col]
    slope = (hi - lo) / (xp[j + 1] - xp[j])
    out = slope * (x - xp[j]) + lo
    if np.isnan(out):
        out = slope * (x - xp[j + 1]) + hi
        if np.isnan(out) and lo == hi:
            out = lo
    return out


@njit
def _accel_towards(s, v, s_tab, table, c, recovery_accel, tau):
    """The along-track acceleration of a governed speed v below the target at s."""
    vt = interp(s, s_tab, table, c + G_TARGET)
    at = interp(s, s_tab, table, c + G_TARGET_ACCEL)
    gap = vt - v
    x = gap / tau if tau > 0.0 else (recovery_accel if gap > 0.0 else 0.0)
    sigma2 = (v / vt) ** 2 if vt > 0.0 else 0.0
    return sigma2 * at + min(max(x, 0.0), recovery_accel)


@njit
def _update(s, along, s_tab, table, c, speed_col, st, k, recovery_accel, tau, band, capped):
    """:meth:`SpeedGovernor.update`: ``(v_g, a_g, retimed)``, the state advanced."""
    vt = interp(s, s_tab, table, c + G_TARGET)
    at = interp(s, s_tab, table, c + G_TARGET_ACCEL)
    v = vt
    if st[k] != 0.0:
        v_last, s_last = st[k + 1], st[k + 2]
        if v_last < interp(s_last, s_tab, table, c + G_TARGET):
            a = _accel_towards(s_last, v_last, s_tab, table, c, recovery_accel, tau)
            v = min(math.sqrt(max(v_last * v_last + 2.0 * a * (s - s_last), 0.0)), vt)
            if vt - v < ON_TARGET_M_S:
                v = vt
    if along < v - band:
        v = max(along + band, 0.0)
    st[k], st[k + 1], st[k + 2] = 1.0, v, s
    if v == vt and not capped:
        return v, at, False
    vp = interp(s, s_tab, table, speed_col)
    ap = interp(s, s_tab, table, c + G_PROFILE_ACCEL)
    a = at if v == vt else _accel_towards(s, v, s_tab, table, c, recovery_accel, tau)
    return v, a, v != vp or a != ap


@njit
def governed_reference(s, along, s_tab, table, c, speed_col, st, k, gp):
    """The regulator's governed reference at s for a vehicle whose speed along the path is
    ``along``: ``(governed, v_r, a_ff, excess_ahead)`` (the regulator's ``_governed``).

    ``governed`` is False when the nominal is flown as it is; else :math:`v_r` is the speed
    regulated to, :math:`a_{ff}` the along-track acceleration fed forward (the profile's plus
    the filtered excess, pushed beyond the band) and ``excess_ahead`` that excess
    ``COMPENSATION_DT_S`` on. ``gp`` = (recovery accel, recovery time constant, band, gain,
    max accel, 1.0 when the target is capped somewhere, the filter's step (0: none), natural
    frequency and largest rate).
    """
    recovery_accel, tau, band, gain, max_accel, capped, dt, omega, jerk = gp
    v_g, a_g, retimed = _update(s, along, s_tab, table, c, speed_col, st, k, recovery_accel, tau, band,
                                capped > 0.0)
    v_r = min(v_g, along + band)
    push = 0.0
    if v_r != v_g:
        retimed = True
        push = min(gain * (v_g - v_r), max_accel)
    a_bar = interp(s, s_tab, table, c + G_PROFILE_ACCEL)
    excess = a_g + push - a_bar if retimed else 0.0
    if dt > 0.0:
        r = st[k + 4] + dt * (omega * omega * (excess - st[k + 3]) - 2.0 * omega * st[k + 4])
        st[k + 4] = min(max(r, -jerk), jerk)
        st[k + 3] += dt * st[k + 4]
    else:
        st[k + 3], st[k + 4] = excess, 0.0
    if not retimed and abs(st[k + 3]) < 1e-6 and abs(st[k + 4]) < 1e-4:
        st[k + 3] = st[k + 4] = 0.0
        return False, v_r, a_g, 0.0
    later = st[k + 3] + st[k + 4] * AHEAD_S
    return True, v_r, a_bar + st[k + 3], later


@njit
def retiming_force(mass, p, v_bar, a_bar, v, a):
    r""":math:`d = m[(\bar a - a) t + (\bar v^2 - v^2) K]` at the path point ``p`` (18 values)."""
    g = a_bar - a
    h = v_bar ** 2 - v ** 2
    return (mass * (g * p[3] + h * (p[4] * p[12] + p[5] * p[13])),
            mass * (g * p[6] + h * (p[7] * p[12] + p[8] * p[13])),
            mass * (g * p[9] + h * (p[10] * p[12] + p[11] * p[13])))
