r"""The maneuver regulator, paper eq 33: :math:`u = \bar u(s) - K(s)\,w`.

Each step projects the position on the path (s), forms the transverse coordinates w at s,
interpolates the feedforward and the gain tables linearly in s, and maps u to rotor forces
by the inverse of eq 34. The tables are built once by the planner. Where numba is available
the step runs as one compiled kernel (:mod:`mavreg.control.controllers.fastpath`, a few microseconds);
the numpy step below is the reference it is tested against, and runs with ``MAVREG_PURE=1``.

Two departures from the paper, each optional (the controller file's ``allocation:`` and
``speed_governor:`` sections, docs/governor.md): the rotor forces may be allocated within the
rotors' limit, the torques kept and the collective given up first
(:func:`~mavreg.model.mixer.torques_first`); and the nominal may be re-timed to a governed
speed (:mod:`mavreg.control.controllers.governor`), so that a vehicle slowed down is not made to fight
for the profile's speed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ...accel import use_compiled
from ...config.regulation import AllocationParams, SpeedGovernorParams
from ...config.vehicle import VehicleParams
from ...geometry.projection import Projector
from ...model.drag import drag_change_n
from ...model.mixer import Mixer, torques_first, yaw_then_lift
from ...model.rotation import rpy_to_matrix
from ...model.rotor_lag import lag_decay, lag_toward
from ...model.so3 import attitude_error
from . import fastpath
from ..design.actuator import lag_loop_factor
from .attitude_table import NominalAttitudes
from ..estimation.disturbance import DisturbanceEstimate, compensate
from ..estimation.lag_in_effect import RotorLagInEffect
from .governor import GovernedSpeed, SpeedGovernor, along_track_speed, retiming_force, thrust_speed_cap
from ..estimation.torque_bias import allocated_less_bias, bias_vector_n_m
from ..design.transverse import transverse_coordinates

if TYPE_CHECKING:     # an annotation only: control never imports maneuver at run time
    from ...maneuver.plan import Plan

__all__ = ["ManeuverRegulator", "RegulatorOutput"]

_COMPENSATION_DT_S = 0.02
"""Time step of the finite difference that gives the disturbance compensation's turn rate."""


@dataclass(frozen=True)
class RegulatorOutput:
    s: float
    w: np.ndarray
    """Transverse coordinates (11,)."""
    u: np.ndarray
    """(f, g1, g2, g3) commanded."""
    rotor_forces_n: np.ndarray
    """Rotor forces by the inverse of eq 34, allocated by the regulator's method:
    ``torques_first`` keeps them within [0, limit] (:func:`~mavreg.model.mixer.torques_first`);
    ``per_rotor_clip`` lets the yaw torque give way and then lifts all four where one would
    pull (:func:`~mavreg.model.mixer.yaw_then_lift`) and does not clip at the top."""
    in_tube: bool
    finished: bool
    """s has reached the end of the maneuver."""
    speed_ref_m_s: float = math.nan
    """The speed regulated to at s: the governed speed, or the profile's without a governor."""


class ManeuverRegulator:
    """s-scheduled LQR feedback on a :class:`~mavreg.maneuver.plan.Plan`.

    Parameters
    ----------
    plan : Plan
        Nominal and gains (built with the design vehicle).
    vehicle : VehicleParams
        For the mixer (arm length, k).
    control_period_s : float
        The period T at which the command is held (zero-order hold). A held command acts,
        on average, T/2 after the state it was computed from.
    rotor_lag : RotorLagInEffect, optional
        The rotor lag in effect (:mod:`~mavreg.control.estimation.lag_in_effect`), asked at
        each step: a lagged force follows a slowly varying command about tau late, so the
        feedforward leads by its :attr:`~mavreg.control.estimation.lag_in_effect.RotorLagInEffect.applied_s`
        (default: the vehicle file's ``rotor_time_constant_s``; a flight's
        :class:`~mavreg.control.estimation.forecast.Forecaster` has the one that follows the
        in-flight estimate).
    max_compensation_turn_rad : float
        Largest turn of the nominal attitude by the disturbance compensation.
    allocation : AllocationParams, optional
        Allocation method and the rotor limit it counts on (default: ``per_rotor_clip`` at
        the vehicle's ``max_rotor_thrust_n``, the paper's).
    speed_governor : SpeedGovernorParams, optional
        The speed governor (default: none, the paper's regulator).
    compiled : bool, optional
        Step by the compiled kernel (:mod:`mavreg.control.controllers.fastpath`, the same outputs to
        rounding) or by the numpy step below, the reference. None (default): compiled where
        numba is available and ``MAVREG_PURE`` is not set.

    Notes
    -----
    The feedforward is taken where the vehicle will be when the command takes effect:
    at s + v(s) (T/2 + tau). This removes the first-order error of both delays on the
    nominal input, which dominates the tracking error of an aggressive maneuver (on the
    barrel roll in lockstep with a 20 ms motor lag, 4.4 cm without the lead, 0.12 cm with it).

    When the plan's gains know the rotor lag (``plan.rotor_time_constant_s`` > 0, gains
    (4, 15)), the feedback also acts on the achieved wrench's deviation from the nominal,
    ``a = M f - u(s)``, with f the rotor forces when the command takes over: given to
    :meth:`step` (a :class:`~mavreg.control.estimation.predictor.StatePredictor` knows them), or else
    the regulator's own lag filter of its past commands (no transport delay assumed).

    Given a :class:`~mavreg.control.estimation.disturbance.DisturbanceEstimate`, the step regulates about
    the nominal compensated for the force the plan's model misses
    (:func:`~mavreg.control.estimation.disturbance.compensated_nominal`): the same path and speed, with
    the thrust turned and scaled to cancel that force; and its torque bias
    (:mod:`mavreg.control.estimation.torque_bias`) is taken from the torques the rotors are asked for
    and added to those they achieve.
    """

    def __init__(self, plan: Plan, vehicle: VehicleParams, control_period_s: float = 0.0,
                 rotor_lag: RotorLagInEffect | None = None, max_compensation_turn_rad: float = math.pi,
                 allocation: AllocationParams | None = None,
                 speed_governor: SpeedGovernorParams | None = None, compiled: bool | None = None):
        self.plan = plan
        mixer = Mixer.from_vehicle(vehicle)
        alloc = allocation if allocation is not None else AllocationParams(method="per_rotor_clip")
        self._fmax = float(vehicle.max_rotor_thrust_n if alloc.max_rotor_thrust_n is None
                           else alloc.max_rotor_thrust_n)
        self._allocate = torques_first if alloc.method == "torques_first" else yaw_then_lift
        self.mixer_inverse = mixer.inverse
        self._mixer = mixer.matrix
        self._augmented = plan.K.shape[-1] > 11
        self._decay = (lag_decay(control_period_s, plan.rotor_time_constant_s)
                       if self._augmented and control_period_s > 0 else 0.0)
        self.lag_loop_factor = lag_loop_factor(plan.K, self._decay) if self._decay > 0 else 0.0
        """The one-period gain of the feedback on the achieved wrench (at 1 or more the gains
        oscillate between commands: :func:`~mavreg.control.design.actuator.lag_loop_factor`)."""
        self._rotors_est: np.ndarray | None = None
        self.projector = Projector(plan.path)
        self._s = plan.s
        self._x, self._u, self._K = plan.x, plan.u, plan.K
        self._v = plan.speed_m_s
        self._last = len(plan.s) - 2
        self.rotor_lag = RotorLagInEffect.of_vehicle(vehicle) if rotor_lag is None else rotor_lag
        self._half_period_s = control_period_s / 2
        self._lead_s = self._half_period_s + self.rotor_lag.applied_s
        self._base_drag = tuple(float(c) for c in vehicle.rotor_drag_n_s_per_m)
        self._parasitic = float(vehicle.parasitic_drag_n_s2_per_m2)
        self._mass = float(vehicle.mass_kg)
        self._max_turn = float(max_compensation_turn_rad)
        self.governor: SpeedGovernor | None = None
        if speed_governor is not None and speed_governor.enabled:
            cap = (thrust_speed_cap(plan, speed_governor.thrust_share * 4.0 * self._fmax,
                                    speed_governor.recovery_accel_m_s2)
                   if speed_governor.cap_speed_for_thrust else None)
            self.governor = SpeedGovernor(plan.s, plan.speed_m_s, speed_governor, cap)
            self._accel_dt = float(control_period_s)
            self._accel_omega = 1.0 / speed_governor.accel_time_constant_s
            self._accel_jerk = float(speed_governor.max_jerk_m_s3)
        self._accel_excess = 0.0
        """The along-track acceleration fed forward less the profile's (filtered)."""
        self._accel_rate = 0.0
        """Its rate of change (m/s^3)."""
        self._attitudes = (NominalAttitudes(plan.s, plan.R, plan.x[:, 9:12] / plan.speed_m_s[:, None])
                           if plan.attitude_error == "so3" else None)
        """The nominal attitude's rows when the gains are on the SO(3) attitude error."""
        self.s = 0.0
        self._compiled = (self._compiled_step(speed_governor) if use_compiled(compiled, "step") else None)
        """The compiled step (:class:`~mavreg.control.controllers.fastpath.FastStep`), or None: the numpy step."""

    @property
    def compiled_step(self) -> fastpath.FastStep | None:
        """The compiled step this regulator runs (its tables and settings; None: the numpy
        step): what :func:`mavreg.sim.batch.fly_batch` hands its compiled loop."""
        return self._compiled

    def _compiled_step(self, speed_governor) -> fastpath.FastStep:
        """The compiled step with this regulator's tables and settings (the kernel compiled
        or loaded now, not in the loop)."""
        fastpath.warm_up()
        gov = None if self.governor is None else fastpath.GovernorSetup(
            speed_governor, self.governor.target_m_s, self._accel_dt, self._accel_omega, self._accel_jerk,
            self._mass, self._parasitic)
        return fastpath.FastStep(self.plan, self._mixer, self.mixer_inverse, self._fmax,
                                 self._allocate is torques_first, self._lead_s, self._decay,
                                 self._base_drag, self._max_turn, self.projector.window_m,
                                 self.projector.tube_margin, gov)

    def _lead(self) -> None:
        """The feedforward's lead for the rotor lag in effect now."""
        lead = self._half_period_s + self.rotor_lag.applied_s
        if lead != self._lead_s:
            self._lead_s = lead
            if self._compiled is not None:
                self._compiled.set_lead(lead)

    def _extra_force(self, xbar, R, disturbance: DisturbanceEstimate) -> np.ndarray:
        """The force the plan's model misses at nominal state ``xbar`` (attitude ``R``)."""
        return disturbance.extra_force_ned(R, R @ xbar[6:9], self._base_drag)

    def _nominal_attitude(self, i: int, a: float, xbar) -> np.ndarray:
        """Rbar at table row i, fraction a: the plan's rotation rows in the SO(3) form, the
        blended roll-pitch-yaw otherwise."""
        if self._attitudes is not None:
            return self._attitudes.at(i, a)
        return rpy_to_matrix(*xbar[3:6])

    def _locate(self, s: float) -> tuple[int, float]:
        i = min(max(int(np.searchsorted(self._s, s)) - 1, 0), self._last)
        return i, min(max((s - self._s[i]) / (self._s[i + 1] - self._s[i]), 0.0), 1.0)

    def reset(self, x, s_guess: float = 0.0, rotor_forces_n=None) -> None:
        """Start tracking from state x, with s near ``s_guess`` and the rotors at
        ``rotor_forces_n`` (default: the nominal's at s)."""
        self.s = self.projector.reset(np.asarray(x)[:3], s_guess).s
        if self.governor is not None:
            self.governor.reset()
        self._accel_excess = self._accel_rate = 0.0
        if rotor_forces_n is None:
            i, a = self._locate(self.s)
            rotor_forces_n = self.mixer_inverse @ (self._u[i] + a * (self._u[i + 1] - self._u[i]))
        self._rotors_est = np.asarray(rotor_forces_n, dtype=float).copy()
        if self._compiled is not None:
            self._compiled.reset(self.s, self._rotors_est)

    def _governed(self, s: float, pt, x) -> tuple[GovernedSpeed, float] | None:
        r"""The governed reference at s for state x with its along-track acceleration fed
        forward, and that acceleration's excess over the profile's ``_COMPENSATION_DT_S``
        later; None when the nominal is not re-timed.

        The excess e follows its target :math:`e^* = a_g + a_{push} - \bar a` through a
        critically damped second-order filter of time constant :math:`\tau_a`
        (``accel_time_constant_s``), its rate bounded by ``max_jerk_m_s3``:
        :math:`\dot r = (e^* - e)/\tau_a^2 - 2r/\tau_a`, :math:`\dot e = r`, one explicit step
        per control period (none without a period: e = e*). Its rate is continuous, so is
        the turn rate of the re-timed attitude (a step of it excites the roll loop of a design
        that does not know the rotors' lag)."""
        R = rpy_to_matrix(*x[3:6])
        gov, push = self.governor.reference(s, along_track_speed(pt.frame[:, 0], R @ x[6:9]))
        a_bar = self.governor.profile(s)[1]
        excess = gov.accel_m_s2 + push - a_bar if gov.retimed else 0.0
        if self._accel_dt > 0.0:
            w, dt = self._accel_omega, self._accel_dt
            r = self._accel_rate + dt * (w * w * (excess - self._accel_excess) - 2.0 * w * self._accel_rate)
            self._accel_rate = min(max(r, -self._accel_jerk), self._accel_jerk)
            self._accel_excess += dt * self._accel_rate
        else:
            self._accel_excess, self._accel_rate = excess, 0.0
        if not gov.retimed and abs(self._accel_excess) < 1e-6 and abs(self._accel_rate) < 1e-4:
            self._accel_excess = self._accel_rate = 0.0
            return None
        later = self._accel_excess + self._accel_rate * _COMPENSATION_DT_S
        return GovernedSpeed(gov.speed_m_s, a_bar + self._accel_excess, True), later

    def _retimed(self, s: float, xbar, R, thrust_n: float, gov: GovernedSpeed):
        r"""The nominal at s flown at the governed speed: body velocity and rates scaled by
        :math:`\sigma = v_g/\bar v`, the thrust vector changed by
        :func:`~mavreg.control.controllers.governor.retiming_force` (no turn rate: see :meth:`step`)."""
        v_bar, a_bar = self.governor.profile(s)
        sigma = gov.speed_m_s / v_bar
        x = xbar.copy()
        x[6:12] *= sigma
        pt = self.plan.path.point(s)
        drag = self._drag_change(R, R @ xbar[6:9], sigma)
        d = retiming_force(self._mass, pt.frame[:, 0], pt.curvature_vector, v_bar, a_bar,
                           gov.speed_m_s, gov.accel_m_s2, drag)
        return x, d, sigma

    def _drag_change(self, R, v_bar_ned, sigma: float):
        """The modelled drag at velocity sigma * v_bar less the drag at v_bar (None: no drag)."""
        cxy, cz = self._base_drag
        if not (cxy or cz or self._parasitic):
            return None
        return drag_change_n(R, v_bar_ned, sigma, cxy, cz, self._parasitic)

    def _feedback(self, ubar, u_here, K, w, rotor_forces_n, disturbance):
        """The wrench ``u`` (the nominal less the gain on the transverse error and, for
        lag-aware gains, on the achieved wrench's lag) and the rotor forces that give it, less
        the estimated torque bias."""
        tb = None if disturbance is None or not any(disturbance.torque_bias) else disturbance.torque_bias
        if self._augmented:
            f_act = self._rotors_est if rotor_forces_n is None else np.asarray(rotor_forces_n, float)
            if f_act is None:
                f_act = self.mixer_inverse @ u_here
            achieved = self._mixer @ f_act
            if tb is not None:             # the airframe adds its torque bias to the rotors'
                achieved[1:] += bias_vector_n_m(tb, achieved[0])
            u = ubar - K[:, :11] @ w - K[:, 11:] @ (achieved - u_here)
        else:
            u = ubar - K @ w
        if tb is not None:                 # the rotors give the wrench less the bias
            rotors = allocated_less_bias(self._allocate, self.mixer_inverse, u, self._fmax, tb)
        else:
            rotors = self._allocate(self.mixer_inverse, u, self._fmax)
        if self._augmented:
            base = self._rotors_est if self._rotors_est is not None else rotors
            self._rotors_est = lag_toward(base, rotors, self._decay)
        return u, rotors

    def step(self, x, rotor_forces_n=None, disturbance: DisturbanceEstimate | None = None) -> RegulatorOutput:
        """One control step for state x (12,); ``rotor_forces_n`` (4,): the rotors' forces
        when this command takes over (used only by lag-aware gains); ``disturbance``: the
        airframe's estimated force model, compensated. The feedforward leads by the rotor lag
        in effect now (:attr:`rotor_lag`)."""
        self._lead()
        if self._compiled is not None:
            s, w, u, rotors, in_tube, finished, v_ref = self._compiled.step(x, rotor_forces_n, disturbance)
            self.s = self.projector.s = s
            return RegulatorOutput(s, w, u, rotors, in_tube, finished, v_ref)
        x = np.asarray(x, dtype=float)
        proj = self.projector.update(x[:3])
        s = proj.s
        self.s = s
        pt = proj.point
        # Linear interpolation of the tables at s (clamped to the ends).
        i, a = self._locate(s)
        xbar = self._x[i] + a * (self._x[i + 1] - self._x[i])
        Rbar = self._nominal_attitude(i, a, xbar)
        Rbar_plan = Rbar
        K = self._K[i] + a * (self._K[i + 1] - self._K[i])
        u_here = self._u[i] + a * (self._u[i + 1] - self._u[i])
        v = float(self._v[i] + a * (self._v[i + 1] - self._v[i]))
        gov = self._governed(s, pt, x) if self.governor is not None else None
        v_ref = v if gov is None else gov[0].speed_m_s
        if self._lead_s > 0.0:
            i, a = self._locate(s + v_ref * self._lead_s)
        ubar = self._u[i] + a * (self._u[i + 1] - self._u[i])
        if gov is not None or disturbance is not None:
            # the turn rate of the changed nominal from the nominal _COMPENSATION_DT_S ahead
            s_ahead = s + max(v_ref, 0.1) * _COMPENSATION_DT_S
            j, b = self._locate(s_ahead)
            x_ahead = self._x[j] + b * (self._x[j + 1] - self._x[j])
            R_ahead = self._nominal_attitude(j, b, x_ahead)
            t_ahead = float(self._u[j, 0] + b * (self._u[j + 1, 0] - self._u[j, 0]))
            thrust = float(u_here[0])
            if gov is not None:
                gov, excess_ahead = gov
                ds = s_ahead - s
                gov_ahead = GovernedSpeed(math.sqrt(max(v_ref * v_ref + 2.0 * gov.accel_m_s2 * ds, 0.0)),
                                          self.governor.profile(s_ahead)[1] + excess_ahead, True)
                xa, d_ahead, _ = self._retimed(s_ahead, x_ahead, R_ahead, t_ahead, gov_ahead)
                xbar, d, sigma = self._retimed(s, xbar, Rbar, thrust, gov)
                x_ahead, t_ahead_g, R_ahead_g = compensate(xa, R_ahead, t_ahead, d_ahead)
                xbar, thrust, Rbar = compensate(xbar, Rbar, thrust, d, R_ahead, t_ahead, d_ahead,
                                                _COMPENSATION_DT_S)
                t_ahead, R_ahead = t_ahead_g, R_ahead_g
                torque_scale = sigma * sigma
                ubar = ubar.copy()
                u_here = u_here.copy()
                ubar[1:] *= torque_scale
                u_here[1:] *= torque_scale
            if disturbance is not None:
                xbar, thrust, Rbar = compensate(
                    xbar, Rbar, thrust, self._extra_force(xbar, Rbar, disturbance), R_ahead, t_ahead,
                    self._extra_force(x_ahead, R_ahead, disturbance), _COMPENSATION_DT_S, self._max_turn)
            ubar = ubar.copy()
            ubar[0] += thrust - u_here[0]
            u_here = u_here.copy()
            u_here[0] = thrust
        w = transverse_coordinates(x[:3], pt.frame, pt.position, x, xbar,
                                   Rbar=Rbar_plan if self._attitudes is not None else None)
        if self._attitudes is not None and Rbar is not Rbar_plan:
            # the error from the changed nominal, in the plan's nominal frame, where the gains
            # were designed: e = Log(Rbar^T R) - Log(Rbar^T Rbar_changed)
            w[2:5] -= attitude_error(Rbar_plan, Rbar)
        u, rotors = self._feedback(ubar, u_here, K, w, rotor_forces_n, disturbance)
        return RegulatorOutput(s, w, u, rotors, proj.in_tube, s >= self.plan.length_m - 1e-6, v_ref)
