r"""The maneuver regulator's step as one scalar kernel that numba compiles
(:func:`mavreg.accel.njit`): :meth:`mavreg.control.controllers.regulator.ManeuverRegulator.step`, state
in, rotor forces out, nothing allocated but scratch rows.

One step, as the regulator does it:

1. s by the warm-started projection (:func:`mavreg.geometry.projection_kernel.project`);
2. one row blend of the plan's table at s, :math:`r = T_i + a (T_{i+1} - T_i)`, giving
   :math:`\bar x(s)`, :math:`\bar u(s)`, :math:`\bar v(s)` and :math:`K(s)` at once
   (:data:`TABLE_X`, :data:`TABLE_U`, :data:`TABLE_V`, :data:`TABLE_K`), and the nominal
   attitude :math:`\bar R(s)`: from the blended roll-pitch-yaw, or in the SO(3) form
   :math:`R_i \mathrm{Exp}(\xi(a))` from the row's attitude data;
3. with a speed governor, the speed :math:`v_r` regulated to and the along-track
   acceleration fed forward (:mod:`mavreg.control.controllers.governor_kernel`), else :math:`v_r = \bar v(s)`;
4. the feedforward at :math:`s + v_r\,\ell` (the lead); the nominal re-timed to the governed
   speed (velocities and rates times :math:`\sigma = v_r/\bar v`, torques times
   :math:`\sigma^2`, the thrust vector turned for the re-timing force), and with a disturbance
   estimate compensated for it (:func:`mavreg.control.controllers.compensation_kernel.compensate`, each
   with the nominal :data:`COMPENSATION_DT_S` ahead for the turn's rate);
5. w (:func:`mavreg.control.design.transverse.transverse_coordinates`: the attitude error the
   wrapped roll-pitch-yaw differences, or :math:`\mathrm{Log}(\bar R^T R)` in the plan's
   nominal frame, less :math:`\mathrm{Log}(\bar R^T \bar R_c)` of the compensated
   :math:`\bar R_c`), then
   :math:`u = \bar u - K_{:, 0:11} w - K_{:, 11:15} (M f - \bar u(s))` with lag-aware gains
   (f: the rotor forces handed over, else the regulator's lag filter of its own commands,
   else :math:`M^{-1} \bar u(s)`), or :math:`u = \bar u - K w`;
6. rotor forces by the configured allocation (:func:`yaw_then_lift` or
   :func:`torques_first`, :mod:`mavreg.model.mixer`'s, scalar) of u less the estimated torque
   bias (:mod:`mavreg.control.estimation.torque_bias`; the wrench achieved of step 5 includes it), and
   the lag filter updated.

The tables' layout and the parameter vector's slots are the constants below; the Python side
(:mod:`mavreg.control.controllers.fastpath`) fills them.
"""
from __future__ import annotations

import math

import numpy as np

from ...accel import njit
from ...geometry.projection_kernel import POINT_WIDTH, path_point, project
from ...model.drag_kernel import drag_change
from ...model.mixer_kernel import torques_first, yaw_then_lift
from ...model.rotor_lag_kernel import lag_toward
from ...model.rotation_kernel import log_vee, mm, mtm, mv, rodrigues, rpy_matrix, wrap
from .compensation_kernel import compensate, extra_force
from .governor_kernel import G_PROFILE_ACCEL, governed_reference, interp, retiming_force
from ..estimation.torque_bias import allocate_less_bias, bias_n_m

__all__ = ["regulator_step", "yaw_then_lift", "torques_first", "TABLE_X", "TABLE_U", "TABLE_V",
           "TABLE_K", "ATTITUDE_WIDTH", "P_LEAD", "P_DECAY", "P_FMAX", "P_WINDOW", "P_MARGIN",
           "P_MAX_TURN", "P_CXY", "P_CZ", "P_TORQUES_FIRST", "P_AUGMENTED", "P_END", "P_NK", "P_SO3",
           "P_GOV", "P_GOV_COL", "P_MASS", "P_PARASITIC", "P_GOV_ACCEL", "P_GOV_TAU", "P_GOV_BAND",
           "P_GOV_GAIN", "P_GOV_MAX_ACCEL", "P_GOV_CAPPED", "P_GOV_DT", "P_GOV_OMEGA", "P_GOV_JERK", "P_MINV",
           "P_MIX", "N_PARAMS", "ST_S", "ST_HAS_EST", "ST_EST", "ST_GOV", "ST_WIDTH", "OUT_S", "OUT_W",
           "OUT_U", "OUT_ROTORS", "OUT_WIDTH", "COMPENSATION_DT_S"]

class _Layout:
    """Consecutive slots of a float vector, declared once: each call returns the next field's
    first slot and reserves ``width`` slots; ``width`` is then the vector's size. The module's
    constants below are plain ints made at import, which numba compiles in as constants, and
    the packer (:mod:`mavreg.control.controllers.fastpath`), this kernel and its warm-up all read them:
    a new parameter is one line here, one in the packer and its use in the kernel."""

    def __init__(self):
        self.width = 0

    def __call__(self, width: int = 1) -> int:
        first = self.width
        self.width += width
        return first


_table = _Layout()
TABLE_X = _table(12)
TABLE_U = _table(4)
TABLE_V = _table(1)
TABLE_K = _table(0)
"""Columns of a table row: x (12), u (4), v (1), K row-major (4 x n_K, n_K 11 or 15), then
in the SO(3) form the row's attitude R_i (9, row-major), d_i = Log(R_i^T R_{i+1}) and the
Hermite slopes m0_i, m1_i (3 each) of :class:`mavreg.control.controllers.attitude_table.NominalAttitudes`
(the rows are blended up to the end of K only)."""
ATTITUDE_WIDTH = 18
"""Columns of a row's attitude data (SO(3) form)."""

_prm = _Layout()
P_LEAD = _prm()
"""The feedforward's lead (s)."""
P_DECAY = _prm()
"""The rotor lag filter's decay per step."""
P_FMAX = _prm()
"""The allocation's rotor limit (N)."""
P_WINDOW = _prm()
"""The projection's window (m)."""
P_MARGIN = _prm()
"""The projection's tube margin."""
P_MAX_TURN = _prm()
"""The largest compensating turn (rad)."""
P_CXY = _prm()
P_CZ = _prm()
"""The design's drag (c_xy, c_z), which the disturbance estimate's is compared with."""
P_TORQUES_FIRST = _prm()
"""1.0 for ``torques_first`` (else ``yaw_then_lift``)."""
P_AUGMENTED = _prm()
"""1.0 for lag-aware gains."""
P_END = _prm()
"""The arc length at which the maneuver is finished."""
P_NK = _prm()
"""n_K, the gains' columns."""
P_SO3 = _prm()
"""1.0 for the SO(3) attitude error (else roll-pitch-yaw differences)."""
P_GOV = _prm()
"""1.0 when the speed governor is on."""
P_GOV_COL = _prm()
"""Its first table column."""
P_MASS = _prm()
P_PARASITIC = _prm()
"""The mass (kg) and parasitic drag of the re-timing force."""
P_GOV_ACCEL = _prm()
"""From here to :data:`P_GOV_JERK`, in this order,
:func:`~mavreg.control.controllers.governor_kernel.governed_reference`'s ``gp``: the recovery
acceleration and time constant, the band, the gain, the largest push, 1.0 when the target is
capped somewhere, the fed-forward acceleration's filter step (the control period), natural
frequency and largest rate."""
P_GOV_TAU = _prm()
P_GOV_BAND = _prm()
P_GOV_GAIN = _prm()
P_GOV_MAX_ACCEL = _prm()
P_GOV_CAPPED = _prm()
P_GOV_DT = _prm()
P_GOV_OMEGA = _prm()
P_GOV_JERK = _prm()
P_MINV = _prm(16)
"""M^{-1} of eq 34, row-major."""
P_MIX = _prm(16)
"""M of eq 34, row-major."""
N_PARAMS = _prm.width

_st = _Layout()
ST_S = _st()
"""The state vector kept between steps: s, """
ST_HAS_EST = _st()
"""1.0 when the lag filter holds an estimate,"""
ST_EST = _st(4)
"""the estimate (4),"""
ST_GOV = _st(5)
"""the governor's five slots (:mod:`mavreg.control.controllers.governor_kernel`; a state without a
governor may end here)."""
ST_WIDTH = _st.width

_out = _Layout()
OUT_S = _out()
OUT_W = _out(11)
OUT_U = _out(4)
OUT_ROTORS = _out(4)
"""The output vector: s, w (11), u (4), rotor forces (4)."""
OUT_WIDTH = _out.width
COMPENSATION_DT_S = 0.02
"""As the regulator's ``_COMPENSATION_DT_S``."""


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
def _retimed(s, xb, R, pt, v, a, s_tab, table, c, prm):
    r"""The nominal ``xb`` at s re-timed in place to speed v and along-track acceleration a
    (body velocity and rates times :math:`\sigma = v/\bar v`); returns :math:`\sigma` and the
    force by which its thrust vector must change (the regulator's ``_retimed``), ``pt`` the
    path's 18 values at s."""
    v_bar = interp(s, s_tab, table, TABLE_V)
    sigma = v / v_bar
    d = retiming_force(prm[P_MASS], pt, v_bar, interp(s, s_tab, table, c + G_PROFILE_ACCEL), v, a)
    cxy, cz, parasitic = prm[P_CXY], prm[P_CZ], prm[P_PARASITIC]
    if cxy != 0.0 or cz != 0.0 or parasitic != 0.0:
        e = drag_change(R, *mv(R, xb[6], xb[7], xb[8]), sigma, cxy, cz, parasitic)
        d = (d[0] + e[0], d[1] + e[1], d[2] + e[2])
    for k in range(6, 12):
        xb[k] *= sigma
    return sigma, d


@njit
def _compensated(s, p, v_ref, a_ff, later, governed, has_dist, dcxy, dcz, fx, fy, fz, table, s_tab, s_nodes,
                 coef, ends, prm, row, width, so3, Rbar):
    """Step 4's changes of the nominal in ``row`` (x-bar, u-bar and the thrust, in place): the
    governed re-timing and the disturbance compensation; returns the changed nominal attitude."""
    xbar = row[TABLE_X:TABLE_X + 12]
    u_here = row[TABLE_U:TABLE_U + 4]
    ubar = row[width:width + 4]
    # the turn rate of the changed nominal from the nominal COMPENSATION_DT_S ahead
    x_ahead = row[width + 4:width + 16]
    s_ahead = s + max(v_ref, 0.1) * COMPENSATION_DT_S
    j, b = _locate(s_ahead, s_tab)
    _blend(table, j, b, TABLE_X, TABLE_X + 12, x_ahead)
    R_ahead = (_nominal_attitude(table, j, b, width) if so3
               else rpy_matrix(x_ahead[3], x_ahead[4], x_ahead[5]))
    t_ahead = table[j, TABLE_U] + b * (table[j + 1, TABLE_U] - table[j, TABLE_U])
    thrust = u_here[0]
    if governed:
        q = np.empty(POINT_WIDTH)
        path_point(s_ahead, s_nodes, coef, ends, q)
        c = int(prm[P_GOV_COL])
        v_ahead = math.sqrt(max(v_ref * v_ref + 2.0 * a_ff * (s_ahead - s), 0.0))
        a_ahead = interp(s_ahead, s_tab, table, c + G_PROFILE_ACCEL) + later
        da = _retimed(s_ahead, x_ahead, R_ahead, q, v_ahead, a_ahead, s_tab, table, c, prm)[1]
        sigma, d = _retimed(s, xbar, Rbar, p, v_ref, a_ff, s_tab, table, c, prm)
        t_ahead_g, R_ahead_g = compensate(x_ahead, R_ahead, t_ahead, da[0], da[1], da[2], R_ahead, 0.0,
                                          0.0, 0.0, 0.0, 0.0, math.pi)
        thrust, Rbar = compensate(xbar, Rbar, thrust, d[0], d[1], d[2], R_ahead, t_ahead, da[0], da[1],
                                  da[2], COMPENSATION_DT_S, math.pi)
        t_ahead, R_ahead = t_ahead_g, R_ahead_g
        for r in range(1, 4):
            ubar[r] *= sigma * sigma
            u_here[r] *= sigma * sigma
    if has_dist:
        dcxy -= prm[P_CXY]
        dcz -= prm[P_CZ]
        f0, f1, f2 = extra_force(Rbar, *mv(Rbar, xbar[6], xbar[7], xbar[8]), dcxy, dcz, fx, fy, fz)
        g0, g1, g2 = extra_force(R_ahead, *mv(R_ahead, x_ahead[6], x_ahead[7], x_ahead[8]), dcxy, dcz,
                                 fx, fy, fz)
        thrust, Rbar = compensate(xbar, Rbar, thrust, f0, f1, f2, R_ahead, t_ahead, g0, g1, g2,
                                  COMPENSATION_DT_S, prm[P_MAX_TURN])
    ubar[0] += thrust - u_here[0]
    u_here[0] = thrust
    return Rbar


@njit
def _feedback(x, p, R_plan, Rbar, compensated, row, width, nk, so3, prm, st, f_act, has_f, tb, out):
    """Steps 5 and 6: w, u and the rotor forces into ``out``, and the lag filter updated;
    ``tb`` (6,) the airframe's torque bias (:mod:`mavreg.control.estimation.torque_bias`): added to the
    wrench the rotors achieve, taken from the one they are asked for."""
    xbar = row[TABLE_X:TABLE_X + 12]
    u_here = row[TABLE_U:TABLE_U + 4]
    ubar = row[width:width + 4]
    K = row[TABLE_K:width]
    w = out[OUT_W:OUT_W + 11]
    d0, d1, d2 = x[0] - p[0], x[1] - p[1], x[2] - p[2]
    w[0] = d0 * p[4] + d1 * p[7] + d2 * p[10]
    w[1] = d0 * p[5] + d1 * p[8] + d2 * p[11]
    if so3:
        # in the plan's nominal frame, where the gains were designed; with a compensation,
        # the error from the changed nominal: Log(Rbar^T R) - Log(Rbar^T Rbar_changed)
        w[2], w[3], w[4] = log_vee(mtm(R_plan, rpy_matrix(x[3], x[4], x[5])))
        if compensated:
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
        fa = f_act if has_f else st[ST_EST:ST_EST + 4]
        if not has_f and st[ST_HAS_EST] == 0.0:
            fa = np.empty(4)
            for r in range(4):
                fa[r] = (minv[4 * r] * u_here[0] + minv[4 * r + 1] * u_here[1]
                         + minv[4 * r + 2] * u_here[2] + minv[4 * r + 3] * u_here[3])
        mix = prm[P_MIX:P_MIX + 16]
        dev = np.empty(4)
        for c in range(4):
            dev[c] = (mix[4 * c] * fa[0] + mix[4 * c + 1] * fa[1] + mix[4 * c + 2] * fa[2]
                      + mix[4 * c + 3] * fa[3])
        for c in range(3):
            dev[1 + c] += bias_n_m(tb, dev[0], c)
        for c in range(4):
            dev[c] -= u_here[c]
        for r in range(4):
            acc = 0.0
            for c in range(4):
                acc += K[r * nk + 11 + c] * dev[c]
            u[r] -= acc
    rotors = out[OUT_ROTORS:OUT_ROTORS + 4]
    allocate_less_bias(minv, u, prm[P_FMAX], tb, prm[P_TORQUES_FIRST] > 0.0, rotors)
    if augmented:
        decay = prm[P_DECAY]
        for r in range(4):
            base = st[ST_EST + r] if st[ST_HAS_EST] != 0.0 else rotors[r]
            st[ST_EST + r] = lag_toward(base, rotors[r], decay)
        st[ST_HAS_EST] = 1.0


@njit
def regulator_step(x, f_act, has_f, has_dist, dcxy, dcz, fx, fy, fz, tb, table, s_tab, s_nodes, coef,
                   ends, prm, st, out):
    """One step for state x (12,); returns ``(s, in_tube, finished, v_ref)``.

    ``f_act`` (4,): the rotor forces handed over (used when ``has_f``); ``dcxy ... fz``: the
    disturbance estimate's drag and its constant force (used when ``has_dist``); ``tb`` (6,):
    its torque bias (zeros: none, :mod:`mavreg.control.estimation.torque_bias`). ``st``
    (:data:`ST_WIDTH`,; 6 without a governor) is the state kept between steps. ``out``
    (:data:`OUT_WIDTH`,) receives s, w, u and the rotor forces.
    """
    p = np.empty(POINT_WIDTH)
    s, inside, _ = project(x[0], x[1], x[2], st[ST_S], prm[P_WINDOW], prm[P_MARGIN], s_nodes, coef, ends, p)
    st[ST_S] = s
    nk = int(prm[P_NK])
    width = TABLE_K + 4 * nk           # the blended columns; the attitude data follow
    so3 = prm[P_SO3] > 0.0
    row = np.empty(width + 16)
    i, a = _locate(s, s_tab)
    _blend(table, i, a, 0, width, row)
    xbar = row[TABLE_X:TABLE_X + 12]
    v_ref = row[TABLE_V]
    Rbar = _nominal_attitude(table, i, a, width) if so3 else rpy_matrix(xbar[3], xbar[4], xbar[5])
    R_plan = Rbar
    governed = False
    a_ff = later = 0.0
    if prm[P_GOV] > 0.0:
        n0, n1, n2 = mv(rpy_matrix(x[3], x[4], x[5]), x[6], x[7], x[8])
        governed, v_gov, a_ff, later = governed_reference(
            s, p[3] * n0 + p[6] * n1 + p[9] * n2, s_tab, table, int(prm[P_GOV_COL]), TABLE_V, st, ST_GOV,
            (prm[P_GOV_ACCEL], prm[P_GOV_TAU], prm[P_GOV_BAND], prm[P_GOV_GAIN], prm[P_GOV_MAX_ACCEL],
             prm[P_GOV_CAPPED], prm[P_GOV_DT], prm[P_GOV_OMEGA], prm[P_GOV_JERK]))
        if governed:
            v_ref = v_gov
    ubar = row[width:width + 4]
    if prm[P_LEAD] > 0.0:
        i, a = _locate(s + v_ref * prm[P_LEAD], s_tab)
    _blend(table, i, a, TABLE_U, TABLE_U + 4, ubar)
    compensated = governed or has_dist
    if compensated:
        Rbar = _compensated(s, p, v_ref, a_ff, later, governed, has_dist, dcxy, dcz, fx, fy, fz, table, s_tab,
                            s_nodes, coef, ends, prm, row, width, so3, Rbar)
    _feedback(x, p, R_plan, Rbar, compensated, row, width, nk, so3, prm, st, f_act, has_f, tb, out)
    out[OUT_S] = s
    return s, inside, s >= prm[P_END], v_ref

