r"""The predictor's command history: the rotors' lag filter and a horizon's segments, one kernel.

:class:`mavreg.control.estimation.predictor.StatePredictor` keeps the commands sent as two preallocated
arrays, ``ct`` (the vehicle time of the sample each answered) and ``cc`` (their four rotor
commands), live in rows ``lo:hi`` in increasing time. A command answering the sample of time
:math:`t_j` acts from :math:`t_j + D` (``delay_s``) until the next one takes over.
:func:`prepare` does, for every prediction, what was Python around the integration kernel:

1. advances the rotors' first-order lag (time constant :math:`\tau`) to the sample time,
   exactly, over the commands that have acted since the last call
   (:math:`f \leftarrow c + (f - c)e^{-\Delta/\tau}`; :math:`f = c` for ideal rotors), and
   drops the commands fully acted;
2. writes the segments of the horizon :math:`[t_s, t_{end})` for
   :func:`mavreg.control.estimation.predictor_kernel.predict_into`: row 0 the command in force at
   :math:`t_s` (else the rotors' own state), then each command that starts inside, then
   :math:`t_{end}`.

``rot`` (5,), read and overwritten: the time the filter stands at and the four forces.
Compiled by numba where available (:func:`mavreg.accel.njit`), plain Python with
``MAVREG_PURE=1``: the reference ``tests/unit/test_predictor.py`` holds it to.
"""
from __future__ import annotations

import math

from ...accel import njit
from ...model.rotor_lag_kernel import lag_after4

__all__ = ["advance", "prepare"]


@njit
def advance(rot, ct, cc, lo, hi, t_s, delay_s, tau):
    """The lag filter ``rot`` advanced to ``t_s`` over the commands ``lo:hi``; returns the new
    ``lo`` (the commands that have fully acted are dropped). A ``t_s`` at or before the
    filter's time changes nothing."""
    t = rot[0]
    if t_s <= t:
        return lo
    f0, f1, f2, f3 = rot[1], rot[2], rot[3], rot[4]
    while lo < hi:
        start = ct[lo] + delay_s
        if start >= t_s:
            break
        end = ct[lo + 1] + delay_s if hi - lo > 1 else math.inf
        a = max(start, t)
        b = min(end, t_s)
        if b > a:
            c0, c1, c2, c3 = cc[lo, 0], cc[lo, 1], cc[lo, 2], cc[lo, 3]
            f0, f1, f2, f3 = lag_after4(f0, f1, f2, f3, c0, c1, c2, c3, b - a, tau)
            t = b
        if end <= t_s and hi - lo > 1:
            lo += 1
        else:
            break
    rot[0], rot[1], rot[2], rot[3], rot[4] = t_s, f0, f1, f2, f3
    return lo


@njit
def prepare(seg, rot, ct, cc, lo, hi, t_s, t_end, delay_s, tau):
    """:func:`advance` to ``t_s``, then the horizon's segments into ``seg`` (rows 0..n-1, see
    the module docstring). Returns ``(lo, n)``: the new first live command and the rows
    written."""
    lo = advance(rot, ct, cc, lo, hi, t_s, delay_s, tau)
    seg[0, 0], seg[0, 1], seg[0, 2], seg[0, 3], seg[0, 4] = t_s, rot[1], rot[2], rot[3], rot[4]
    n = 1
    for j in range(lo, hi):
        start = ct[j] + delay_s
        if start <= t_s:
            seg[0, 1], seg[0, 2], seg[0, 3], seg[0, 4] = cc[j, 0], cc[j, 1], cc[j, 2], cc[j, 3]
        elif start < t_end:
            seg[n, 0], seg[n, 1], seg[n, 2], seg[n, 3], seg[n, 4] = start, cc[j, 0], cc[j, 1], cc[j, 2], cc[j, 3]
            n += 1
        else:
            break                        # later commands start later still
    seg[n, 0], seg[n, 1], seg[n, 2], seg[n, 3], seg[n, 4] = t_end, 0.0, 0.0, 0.0, 0.0
    return lo, n + 1
