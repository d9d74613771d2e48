r"""The compiled step of the maneuver regulator: tables, state and the call of the kernel.

:class:`FastStep` holds what :func:`mavreg.control.controllers.step_kernel.regulator_step` reads: the
plan laid out as one contiguous (N, 17 + 4 n_K) table (x, u, v and K per node, so that one
row blend gives them all; then the SO(3) form's attitude rows and the speed governor's
columns where they are used), the path's Hermite tables, a parameter vector, and the state
kept between steps (s, the rotor lag filter, the governor). A step costs one kernel call,
one small array for the outputs (w, u and the rotor forces are views of it, fresh every
step, so a caller may keep them) and the :class:`~mavreg.control.controllers.regulator.RegulatorOutput`.

The compiled path is used when numba is available and ``MAVREG_PURE`` is not set
(:data:`mavreg.accel.ACCELERATED`); otherwise the regulator's numpy step runs, the
reference that the tests hold this one to (``tests/unit/test_fastpath.py``: rotor forces
within 1e-9 N over closed-loop states).
:func:`warm_up` compiles (or loads from numba's on-disk cache) the kernel when the
regulator is built, so that no compilation falls inside a control loop. Nothing here reads a
clock: a caller that wants the warm-up timed times the call (``benchmarks/bench_step.py``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...accel import ACCELERATED
from ...config.regulation import SpeedGovernorParams
from ...geometry.projection_kernel import path_tables
from . import step_kernel as sk
from .attitude_table import NominalAttitudes

__all__ = ["FastStep", "GovernorSetup", "plan_table", "step_params", "warm_up"]

_warm = False
"""Whether :func:`warm_up` has run the kernel in this process."""


def warm_up() -> bool:
    """Compile the kernel (or load it from numba's on-disk cache) once per process, by
    running it on a two-node straight path; True when the compiled step is in use (and now
    compiled), False without numba (nothing to compile). Types, not values, select what numba
    compiles, so this one call covers every step: the regulator calls it when it is built
    (the daemon builds it before the maneuver), so that no compilation falls in the loop.
    The caller times the call if it wants the compile time: no clock is read here."""
    global _warm
    if not ACCELERATED:
        return False
    if _warm:
        return True
    coef = np.zeros((1, 4, 18))
    coef[0, 0, 3:12] = np.eye(3).reshape(9)
    coef[0, 1, 0] = 1.0
    ends = np.zeros((2, 18))
    ends[:, 3:12] = np.eye(3).reshape(9)
    ends[1, 0] = 1.0
    prm = step_params(np.eye(4), np.eye(4), n_k=15, so3=True)
    table = np.zeros((2, sk.TABLE_K + 60 + sk.ATTITUDE_WIDTH))
    table[:, sk.TABLE_K + 60:sk.TABLE_K + 69] = np.eye(3).reshape(9)
    sk.regulator_step(np.zeros(12), np.zeros(4), True, True, 0.0, 0.0, 0.0, 0.0, 0.0, np.zeros(6), table,
                      np.array([0.0, 1.0]), np.array([0.0, 1.0]), coef, ends, prm, np.zeros(sk.ST_WIDTH),
                      np.empty(sk.OUT_WIDTH))
    _warm = True
    return True


def step_params(mixer_matrix, mixer_inverse, max_rotor_thrust_n: float = 0.0, torques_first: bool = False,
                lead_s: float = 0.0, decay: float = 0.0, base_drag_n_s_per_m=(0.0, 0.0),
                max_compensation_turn_rad: float = 0.0, window_m: float = 0.0, tube_margin: float = 0.0, *,
                n_k: int = 11, so3: bool = False, end_m: float = 0.0, governor=None) -> np.ndarray:
    """The step kernel's parameter vector (the slots of :mod:`mavreg.control.controllers.step_kernel`):
    the one packer, used by :class:`FastStep` and by :func:`warm_up`. Arguments as
    :class:`FastStep`'s; ``n_k`` the gains' columns (15: lag-aware), ``so3`` the SO(3)
    attitude error, ``end_m`` the arc length at which the maneuver is finished, ``governor``
    None or ``(first table column, mass_kg, parasitic drag, gp)`` with ``gp`` the nine values
    from :data:`~mavreg.control.controllers.step_kernel.P_GOV_ACCEL` to
    :data:`~mavreg.control.controllers.step_kernel.P_GOV_JERK`."""
    prm = np.zeros(sk.N_PARAMS)
    if governor is not None:
        column, mass_kg, parasitic, gp = governor
        prm[sk.P_GOV], prm[sk.P_GOV_COL] = 1.0, column
        prm[sk.P_MASS], prm[sk.P_PARASITIC] = mass_kg, parasitic
        prm[sk.P_GOV_ACCEL:sk.P_GOV_JERK + 1] = gp
    prm[sk.P_LEAD] = lead_s
    prm[sk.P_DECAY] = decay
    prm[sk.P_FMAX] = max_rotor_thrust_n
    prm[sk.P_WINDOW] = window_m
    prm[sk.P_MARGIN] = tube_margin
    prm[sk.P_MAX_TURN] = max_compensation_turn_rad
    prm[sk.P_CXY], prm[sk.P_CZ] = (float(c) for c in base_drag_n_s_per_m)
    prm[sk.P_TORQUES_FIRST] = 1.0 if torques_first else 0.0
    prm[sk.P_AUGMENTED] = 1.0 if n_k > 11 else 0.0
    prm[sk.P_END] = end_m
    prm[sk.P_NK] = n_k
    prm[sk.P_SO3] = 1.0 if so3 else 0.0
    prm[sk.P_MINV:sk.P_MINV + 16] = np.asarray(mixer_inverse, dtype=float).reshape(16)
    prm[sk.P_MIX:sk.P_MIX + 16] = np.asarray(mixer_matrix, dtype=float).reshape(16)
    return prm


def plan_table(plan) -> tuple[np.ndarray, np.ndarray]:
    """``(s (N,), table (N, 17 + 4 n_K [+ 18]))``: the plan's nodes and, per node, x (12),
    u (4), v and K (4, n_K) row-major, at the columns
    :data:`~mavreg.control.controllers.step_kernel.TABLE_X` ... :data:`~mavreg.control.controllers.step_kernel.TABLE_K`;
    for gains on the SO(3) attitude error the row's attitude data follow
    (:class:`~mavreg.control.controllers.attitude_table.NominalAttitudes`: R_i, d_i, m0_i, m1_i; zero
    past the last interval)."""
    n = len(plan.s)
    columns = [plan.x, plan.u, np.asarray(plan.speed_m_s, float).reshape(n, 1), plan.K.reshape(n, -1)]
    if _so3(plan):
        att = NominalAttitudes(plan.s, plan.R, plan.x[:, 9:12] / plan.speed_m_s[:, None])
        pad = np.zeros((1, 3))
        columns += [att.R.reshape(n, 9)] + [np.concatenate([m, pad]) for m in (att.d, att.m0, att.m1)]
    table = np.concatenate(columns, axis=1)
    return np.ascontiguousarray(plan.s, dtype=float), np.ascontiguousarray(table, dtype=float)


def _so3(plan) -> bool:
    """Whether the plan's gains are on the SO(3) attitude error."""
    return getattr(plan, "attitude_error", "rpy") == "so3"


@dataclass(frozen=True)
class GovernorSetup:
    """What the compiled step needs of the regulator's speed governor
    (:class:`~mavreg.control.controllers.governor.SpeedGovernor`, docs/governor.md)."""

    params: SpeedGovernorParams
    target_m_s: np.ndarray
    """The governor's target speed on the plan's grid (the profile, capped for thrust)."""
    filter_dt_s: float
    """The fed-forward acceleration's filter step: the control period (0: no filter)."""
    filter_rate_per_s: float
    """Its natural frequency, 1 / ``accel_time_constant_s``."""
    max_jerk_m_s3: float
    """The bound on its rate."""
    mass_kg: float
    parasitic_drag_n_s2_per_m2: float


def _governor_columns(plan, target_m_s) -> np.ndarray:
    """(N, 3): the target speed, its :math:`v_t v_t'` and the profile's :math:`\bar v \bar v'`
    (as :class:`~mavreg.control.controllers.governor.SpeedGovernor` forms them)."""
    s = np.asarray(plan.s, dtype=float)
    target = np.asarray(target_m_s, dtype=float)
    profile = np.asarray(plan.speed_m_s, dtype=float)
    return np.column_stack([target, np.gradient(0.5 * target * target, s), np.gradient(0.5 * profile ** 2, s)])


class FastStep:
    """The regulator's step, compiled.

    Parameters
    ----------
    plan : Plan
    mixer_matrix, mixer_inverse : (4, 4) arrays
        Eq 34 and its inverse.
    max_rotor_thrust_n : float
        The allocation's rotor limit.
    torques_first : bool
        Allocate by :func:`~mavreg.model.mixer.torques_first` (else
        :func:`~mavreg.model.mixer.yaw_then_lift`).
    lead_s, decay : float
        The feedforward's lead, and the rotor lag filter's decay per step.
    base_drag_n_s_per_m : (2,) floats
        The design's drag (c_xy, c_z), which the disturbance estimate's is compared with.
    max_compensation_turn_rad : float
    window_m, tube_margin : float
        The projector's (:class:`~mavreg.geometry.projection.Projector`).
    governor : GovernorSetup, optional
        The speed governor (None: the profile's speed is regulated to).
    """

    def __init__(self, plan, mixer_matrix, mixer_inverse, max_rotor_thrust_n: float, torques_first: bool,
                 lead_s: float, decay: float, base_drag_n_s_per_m, max_compensation_turn_rad: float,
                 window_m: float, tube_margin: float, governor: GovernorSetup | None = None):
        self.s_tab, table = plan_table(plan)
        gov = None
        if governor is not None:
            g = governor.params
            columns = _governor_columns(plan, governor.target_m_s)
            gov = (table.shape[1], governor.mass_kg, governor.parasitic_drag_n_s2_per_m2, (
                g.recovery_accel_m_s2, g.recovery_time_constant_s, g.speed_band_m_s, g.speed_gain_per_s,
                g.max_accel_m_s2, float(np.any(columns[:, 0] < plan.speed_m_s)), governor.filter_dt_s,
                governor.filter_rate_per_s, governor.max_jerk_m_s3))
            table = np.ascontiguousarray(np.concatenate([table, columns], axis=1))
        self.table = table
        self.s_nodes, self.coef, self.ends = path_tables(plan.path)
        self.prm = step_params(mixer_matrix, mixer_inverse, max_rotor_thrust_n, torques_first, lead_s, decay,
                               base_drag_n_s_per_m, max_compensation_turn_rad, window_m, tube_margin,
                               n_k=plan.K.shape[-1], so3=_so3(plan), end_m=plan.length_m - 1e-6, governor=gov)
        self.state = np.zeros(sk.ST_WIDTH)
        """Kept between steps (:data:`~mavreg.control.controllers.step_kernel.ST_S` ...)."""
        self._no_forces = np.zeros(4)
        self._no_torque = np.zeros(6)

    def set_lead(self, lead_s: float) -> None:
        """The feedforward's lead from the next step on (an estimated rotor lag's)."""
        self.prm[sk.P_LEAD] = lead_s

    def reset(self, s: float, rotor_forces_n=None) -> None:
        """Continue from arc length s, the lag filter at ``rotor_forces_n`` (None: empty), the
        governor without a governed speed."""
        self.state[:] = 0.0
        self.state[sk.ST_S] = s
        if rotor_forces_n is not None:
            self.state[sk.ST_HAS_EST] = 1.0
            self.state[sk.ST_EST:sk.ST_EST + 4] = rotor_forces_n

    def step(self, x, rotor_forces_n=None, disturbance=None):
        """The regulator's step (see :meth:`ManeuverRegulator.step`): ``(s, w, u,
        rotor_forces_n, in_tube, finished, speed_ref_m_s)``, the arrays views of one new
        array."""
        if x.__class__ is not np.ndarray or x.dtype != np.float64 or not x.flags.c_contiguous:
            x = np.ascontiguousarray(x, dtype=np.float64)
        if rotor_forces_n is None:
            f, has_f = self._no_forces, False
        else:
            f, has_f = rotor_forces_n, True
            if f.__class__ is not np.ndarray or f.dtype != np.float64 or not f.flags.c_contiguous:
                f = np.ascontiguousarray(f, dtype=np.float64)
        out = np.empty(sk.OUT_WIDTH)
        if disturbance is None:
            s, in_tube, finished, v_ref = sk.regulator_step(
                x, f, has_f, False, 0.0, 0.0, 0.0, 0.0, 0.0, self._no_torque, self.table, self.s_tab,
                self.s_nodes, self.coef, self.ends, self.prm, self.state, out)
        else:
            cxy, cz = disturbance.drag_n_s_per_m
            fx, fy, fz = disturbance.force_ned_n
            s, in_tube, finished, v_ref = sk.regulator_step(
                x, f, has_f, True, float(cxy), float(cz), float(fx), float(fy), float(fz),
                np.array(disturbance.torque_bias, dtype=np.float64), self.table, self.s_tab, self.s_nodes,
                self.coef, self.ends, self.prm, self.state, out)
        return (s, out[sk.OUT_W:sk.OUT_W + 11], out[sk.OUT_U:sk.OUT_U + 4],
                out[sk.OUT_ROTORS:sk.OUT_ROTORS + 4], in_tube, finished, v_ref)
