r"""The maneuver regulator's step as one scalar kernel that numba compiles
(:func:`mavreg.accel.njit`): :meth:`mavreg.control.regulator.ManeuverRegulator.step` without
a speed governor, state in, rotor forces out, nothing allocated but one scratch point.

One step, as the regulator does it:

1. s by the warm-started projection (:func:`mavreg.geometry.projection_kernel.project`);
2. one row blend of the plan's table at s, :math:`r = T_i + a (T_{i+1} - T_i)`, giving
   :math:`\bar x(s)`, :math:`\bar u(s)`, :math:`\bar v(s)` and :math:`K(s)` at once
   (:data:`TABLE_X`, :data:`TABLE_U`, :data:`TABLE_V`, :data:`TABLE_K`), and the nominal
   attitude :math:`\bar R(s)`: from the blended roll-pitch-yaw, or in the SO(3) form
   :math:`R_i \mathrm{Exp}(\xi(a))` from the row's attitude data;
3. the feedforward at :math:`s + \bar v(s)\,\ell` (the lead), and with a disturbance
   estimate the nominal compensated for it
   (:func:`mavreg.control.compensation_kernel.compensate`, with the nominal
   :data:`COMPENSATION_DT_S` ahead for the turn's rate);
4. w (:func:`mavreg.control.transverse.transverse_coordinates`: the attitude error the
   wrapped roll-pitch-yaw differences, or :math:`\mathrm{Log}(\bar R^T R)` in the plan's
   nominal frame, less :math:`\mathrm{Log}(\bar R^T \bar R_c)` of the compensated
   :math:`\bar R_c`), then
   :math:`u = \bar u - K_{:, 0:11} w - K_{:, 11:15} (M f - \bar u(s))` with lag-aware gains
   (f: the rotor forces handed over, else the regulator's lag filter of its own commands,
   else :math:`M^{-1} \bar u(s)`), or :math:`u = \bar u - K w`;
5. rotor forces by the configured allocation (:func:`yaw_then_lift` or
   :func:`torques_first`, :mod:`mavreg.model.mixer`'s, scalar), and the lag filter updated.

The tables' layout and the parameter vector's slots are the constants below; the Python side
(:mod:`mavreg.control.fastpath`) fills them.
"""
from __future__ import annotations

import os

import numpy as np

from ..accel import njit
from ..geometry import projection_kernel
from ..geometry.projection_kernel import POINT_WIDTH, project
from ..model import rotation_kernel
from ..model.rotation_kernel import log_vee, mm, mtm, mv, rodrigues, rpy_matrix, wrap
from . import compensation_kernel
from .compensation_kernel import compensate, extra_force

__all__ = ["regulator_step", "yaw_then_lift", "torques_first", "TABLE_X", "TABLE_U", "TABLE_V",
           "TABLE_K", "ATTITUDE_WIDTH", "P_LEAD", "P_DECAY", "P_FMAX", "P_WINDOW", "P_MARGIN",
           "P_MAX_TURN", "P_CXY", "P_CZ", "P_TORQUES_FIRST", "P_AUGMENTED", "P_END", "P_NK", "P_SO3",
           "P_MINV", "P_MIX", "N_PARAMS", "OUT_S", "OUT_W", "OUT_U", "OUT_ROTORS", "OUT_WIDTH",
           "COMPENSATION_DT_S"]

TABLE_X, TABLE_U, TABLE_V, TABLE_K = 0, 12, 16, 17
"""Columns of a table row: x (12), u (4), v (1), K row-major (4 x n_K, n_K 11 or 15), then
in the SO(3) form the row's attitude R_i (9, row-major), d_i = Log(R_i^T R_{i+1}) and the
Hermite slopes m0_i, m1_i (3 each) of :class:`mavreg.control.attitude_table.NominalAttitudes`
(the rows are blended up to the end of K only)."""
ATTITUDE_WIDTH = 18
"""Columns of a row's attitude data (SO(3) form)."""
(P_LEAD, P_DECAY, P_FMAX, P_WINDOW, P_MARGIN, P_MAX_TURN, P_CXY, P_CZ, P_TORQUES_FIRST,
 P_AUGMENTED, P_END, P_NK, P_SO3) = range(13)
"""Slots of the parameter vector: lead (s), lag filter decay, rotor limit (N), projection
window (m) and tube margin, largest compensating turn (rad), the design's drag (c_xy, c_z),
1.0 for ``torques_first`` (else ``yaw_then_lift``), 1.0 for lag-aware gains, the arc length
at which the maneuver is finished, n_K, 1.0 for the SO(3) attitude error (else roll-pitch-yaw
differences)."""
P_MINV, P_MIX = 16, 32
"""M^{-1} and M (eq 34), row-major, 16 slots each."""
N_PARAMS = 48
OUT_S, OUT_W, OUT_U, OUT_ROTORS = 0, 1, 12, 16
"""The output vector: s, w (11), u (4), rotor forces (4)."""
OUT_WIDTH = 20
COMPENSATION_DT_S = 0.02
"""As the regulator's ``_COMPENSATION_DT_S``."""


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
        if b + y < 0.0:
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
    for r in range(4):
        b, y = _split(Minv, u, r)
        if b + y < 0.0:
            beta = min(beta, max(b, 0.0) / -y)
        elif b + y > F:
            beta = min(beta, max(F - b, 0.0) / y)
    low, high = _fill(Minv, u, beta, f)
    if high - low <= F:
        shift = low if low < 0.0 else (high - F if high > F else 0.0)
        for r in range(4):
            f[r] -= shift
        return
    for r in range(4):
        f[r] = (f[r] - low) * (F / (high - low))


@njit
def _locate(s, s_tab):
    """Row i and blend a of s in the table, clamped to its ends (the regulator's ``_locate``)."""
    i = min(max(np.searchsorted(s_tab, s) - 1, 0), s_tab.shape[0] - 2)
    return i, min(max((s - s_tab[i]) / (s_tab[i + 1] - s_tab[i]), 0.0), 1.0)


@njit
def _blend(table, i, a, c0, c1, out):
    """Columns c0:c1 of the table blended between rows i and i + 1 into ``out``."""
    for c in range(c0, c1):
        lo = table[i, c]
        out[c - c0] = lo + a * (table[i + 1, c] - lo)


@njit
def _nominal_attitude(table, i, a, c0):
    """Rbar at row i, fraction a: R_i Exp(xi(a)), xi the cubic Hermite polynomial of the
    row's attitude data at column c0 (:meth:`NominalAttitudes.at`)."""
    a2 = a * a
    a3 = a2 * a
    h10, h01, h11 = a3 - 2.0 * a2 + a, -2.0 * a3 + 3.0 * a2, a3 - a2
    r = table[i]
    xi0 = h10 * r[c0 + 12] + h01 * r[c0 + 9] + h11 * r[c0 + 15]
    xi1 = h10 * r[c0 + 13] + h01 * r[c0 + 10] + h11 * r[c0 + 16]
    xi2 = h10 * r[c0 + 14] + h01 * r[c0 + 11] + h11 * r[c0 + 17]
    R = (r[c0], r[c0 + 1], r[c0 + 2], r[c0 + 3], r[c0 + 4], r[c0 + 5], r[c0 + 6], r[c0 + 7], r[c0 + 8])
    return mm(R, rodrigues(xi0, xi1, xi2))


@njit
def regulator_step(x, f_act, has_f, has_dist, dcxy, dcz, fx, fy, fz, table, s_tab, s_nodes, coef,
                   ends, prm, st, out):
    """One step for state x (12,); returns ``(s, in_tube, finished, v_ref)``.

    ``f_act`` (4,): the rotor forces handed over (used when ``has_f``); ``dcxy ... fz``: the
    disturbance estimate's drag less the design's and its constant force (used when
    ``has_dist``). ``st`` (6,) is the state between steps: s, 1.0 when the lag filter holds
    an estimate, the estimate (4). ``out`` (:data:`OUT_WIDTH`,) receives s, w, u and the
    rotor forces.
    """
    p = np.empty(POINT_WIDTH)
    s, inside, _ = project(x[0], x[1], x[2], st[0], prm[P_WINDOW], prm[P_MARGIN], s_nodes, coef, ends, p)
    st[0] = s
    nk = int(prm[P_NK])
    width = TABLE_K + 4 * nk           # the blended columns; the attitude data follow
    so3 = prm[P_SO3] > 0.0
    row = np.empty(width + 16)
    i, a = _locate(s, s_tab)
    _blend(table, i, a, 0, width, row)
    xbar = row[TABLE_X:TABLE_X + 12]
    u_here = row[TABLE_U:TABLE_U + 4]
    K = row[TABLE_K:width]
    v_ref = row[TABLE_V]
    Rbar = _nominal_attitude(table, i, a, width) if so3 else rpy_matrix(xbar[3], xbar[4], xbar[5])
    R_plan = Rbar
    ubar = row[width:width + 4]
    if prm[P_LEAD] > 0.0:
        i, a = _locate(s + v_ref * prm[P_LEAD], s_tab)
    _blend(table, i, a, TABLE_U, TABLE_U + 4, ubar)
    if has_dist:
        x_ahead = row[width + 4:width + 16]
        j, b = _locate(s + max(v_ref, 0.1) * COMPENSATION_DT_S, s_tab)
        _blend(table, j, b, TABLE_X, TABLE_X + 12, x_ahead)
        R_ahead = (_nominal_attitude(table, j, b, width) if so3
                   else rpy_matrix(x_ahead[3], x_ahead[4], x_ahead[5]))
        t_ahead = table[j, TABLE_U] + b * (table[j + 1, TABLE_U] - table[j, TABLE_U])
        dcxy -= prm[P_CXY]
        dcz -= prm[P_CZ]
        f0, f1, f2 = extra_force(Rbar, *mv(Rbar, xbar[6], xbar[7], xbar[8]), dcxy, dcz, fx, fy, fz)
        g0, g1, g2 = extra_force(R_ahead, *mv(R_ahead, x_ahead[6], x_ahead[7], x_ahead[8]), dcxy, dcz,
                                 fx, fy, fz)
        thrust, Rbar = compensate(xbar, Rbar, u_here[0], f0, f1, f2, R_ahead, t_ahead, g0, g1, g2,
                                  COMPENSATION_DT_S, prm[P_MAX_TURN])
        ubar[0] += thrust - u_here[0]
        u_here[0] = thrust
    w = out[OUT_W:OUT_W + 11]
    d0, d1, d2 = x[0] - p[0], x[1] - p[1], x[2] - p[2]
    w[0] = d0 * p[4] + d1 * p[7] + d2 * p[10]
    w[1] = d0 * p[5] + d1 * p[8] + d2 * p[11]
    if so3:
        # in the plan's nominal frame, where the gains were designed; with a compensation,
        # the error from the changed nominal: Log(Rbar^T R) - Log(Rbar^T Rbar_changed)
        w[2], w[3], w[4] = log_vee(mtm(R_plan, rpy_matrix(x[3], x[4], x[5])))
        if has_dist:
            c0, c1, c2 = log_vee(mtm(R_plan, Rbar))
            w[2] -= c0
            w[3] -= c1
            w[4] -= c2
    else:
        for j in range(3):
            w[2 + j] = wrap(x[3 + j] - xbar[3 + j])
    for j in range(6):
        w[5 + j] = x[6 + j] - xbar[6 + j]
    u = out[OUT_U:OUT_U + 4]
    for r in range(4):
        acc = 0.0
        for c in range(11):
            acc += K[r * nk + c] * w[c]
        u[r] = ubar[r] - acc
    minv = prm[P_MINV:P_MINV + 16]
    augmented = prm[P_AUGMENTED] > 0.0
    if augmented:
        fa = f_act if has_f else st[2:6]
        if not has_f and st[1] == 0.0:
            fa = np.empty(4)
            for r in range(4):
                fa[r] = (minv[4 * r] * u_here[0] + minv[4 * r + 1] * u_here[1]
                         + minv[4 * r + 2] * u_here[2] + minv[4 * r + 3] * u_here[3])
        mix = prm[P_MIX:P_MIX + 16]
        for r in range(4):
            acc = 0.0
            for c in range(4):
                dev = (mix[4 * c] * fa[0] + mix[4 * c + 1] * fa[1] + mix[4 * c + 2] * fa[2]
                       + mix[4 * c + 3] * fa[3]) - u_here[c]
                acc += K[r * nk + 11 + c] * dev
            u[r] -= acc
    rotors = out[OUT_ROTORS:OUT_ROTORS + 4]
    if prm[P_TORQUES_FIRST] > 0.0:
        torques_first(minv, u, prm[P_FMAX], rotors)
    else:
        yaw_then_lift(minv, u, prm[P_FMAX], rotors)
    if augmented:
        decay = prm[P_DECAY]
        for r in range(4):
            base = st[2 + r] if st[1] != 0.0 else rotors[r]
            st[2 + r] = rotors[r] + (base - rotors[r]) * decay
        st[1] = 1.0
    out[OUT_S] = s
    return s, inside, s >= prm[P_END], v_ref


def _cache_follows(dispatcher, *modules) -> None:
    """Make the on-disk cache of a compiled ``dispatcher`` stale when any of ``modules`` changes.

    numba keys a cached function by the stamp (mtime, size) of its own source file only, so
    the callees it compiles in from other files would be loaded as they were after an edit of
    theirs alone. The stamp is extended with theirs (nothing happens without numba, or where
    its cache is laid out otherwise: then only this file's edits refresh it).
    """
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None or not hasattr(cache_file, "_source_stamp"):
        return
    stamps = tuple((os.stat(m.__file__).st_mtime, os.stat(m.__file__).st_size) for m in modules)
    cache_file._source_stamp = (cache_file._source_stamp, stamps)


_cache_follows(regulator_step, projection_kernel, rotation_kernel, compensation_kernel)
