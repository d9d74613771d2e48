r"""The maneuver regulator, paper eq 33: :math:`u = \bar u(s) - K(s)\,w`.

Each step projects the position on the path (s), forms the transverse coordinates w at s,
interpolates the feedforward and the gain tables linearly in s, and maps u to rotor forces
by the inverse of eq 34. The tables are built once by the planner; a step allocates only
a few small vectors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.vehicle import VehicleParams
from ..geometry.projection import Projector
from ..maneuver.plan import Plan
from ..model.mixer import Mixer, yaw_then_lift
from ..model.rotation import rpy_to_matrix
from .disturbance import DisturbanceEstimate, compensated_nominal
from .transverse import transverse_coordinates

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
    """Rotor forces by the inverse of eq 34; where one would pull, the yaw torque gives way
    and then all four are lifted (:func:`~mavreg.model.mixer.yaw_then_lift`); not clipped at
    the top."""
    in_tube: bool
    finished: bool
    """s has reached the end of the maneuver."""


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
    rotor_time_constant_s : float, optional
        First-order lag tau of the rotors' thrust (default: the vehicle's estimate,
        ``vehicle.rotor_time_constant_s``). A lagged force follows a slowly varying command
        about tau late.
    max_compensation_turn_rad : float
        Largest turn of the nominal attitude by the disturbance compensation.

    Notes
    -----
    The feedforward is taken where the vehicle will be when the command takes effect:
    at s + v(s) (T/2 + tau). This removes the first-order error of both delays on the
    nominal input, which dominates the tracking error of an aggressive maneuver (on the
    barrel roll in lockstep with a 20 ms motor lag, 4.4 cm without the lead, 0.12 cm with it).

    When the plan's gains know the rotor lag (``plan.rotor_time_constant_s`` > 0, gains
    (4, 15)), the feedback also acts on the achieved wrench's deviation from the nominal,
    ``a = M f - u(s)``, with f the rotor forces when the command takes over: given to
    :meth:`step` (a :class:`~mavreg.control.predictor.StatePredictor` knows them), or else
    the regulator's own lag filter of its past commands (no transport delay assumed).

    Given a :class:`~mavreg.control.disturbance.DisturbanceEstimate`, the step regulates about
    the nominal compensated for the force the plan's model misses
    (:func:`~mavreg.control.disturbance.compensated_nominal`): the same path and speed, with
    the thrust turned and scaled to cancel that force.
    """

    def __init__(self, plan: Plan, vehicle: VehicleParams, control_period_s: float = 0.0,
                 rotor_time_constant_s: float | None = None, max_compensation_turn_rad: float = math.pi):
        self.plan = plan
        mixer = Mixer(vehicle.arm_length_m, vehicle.drag_torque_ratio_m)
        self._fmax = float(vehicle.max_rotor_thrust_n)
        self.mixer_inverse = mixer.inverse
        self._mixer = mixer.matrix
        self._augmented = plan.K.shape[-1] > 11
        self._decay = (float(np.exp(-control_period_s / plan.rotor_time_constant_s))
                       if self._augmented and control_period_s > 0 else 0.0)
        self._rotors_est: np.ndarray | None = None
        self.projector = Projector(plan.path)
        self._s = plan.s
        self._x, self._u, self._K = plan.x, plan.u, plan.K
        self._v = plan.speed_m_s
        self._last = len(plan.s) - 2
        tau = vehicle.rotor_time_constant_s if rotor_time_constant_s is None else rotor_time_constant_s
        self._lead_s = control_period_s / 2 + tau
        self._base_drag = tuple(float(c) for c in vehicle.rotor_drag_n_s_per_m)
        self._max_turn = float(max_compensation_turn_rad)
        self.s = 0.0

    def _extra_force(self, xbar, disturbance: DisturbanceEstimate) -> np.ndarray:
        """The force the plan's model misses at nominal state ``xbar``."""
        R = rpy_to_matrix(*xbar[3:6])
        return disturbance.extra_force_ned(R, R @ xbar[6:9], self._base_drag)

    def _locate(self, s: float) -> tuple[int, float]:
        i = min(max(int(np.searchsorted(self._s, s)) - 1, 0), self._last)
        return i, min(max((s - self._s[i]) / (self._s[i + 1] - self._s[i]), 0.0), 1.0)

    def reset(self, x, s_guess: float = 0.0, rotor_forces_n=None) -> None:
        """Start tracking from state x, with s near ``s_guess`` and the rotors at
        ``rotor_forces_n`` (default: the nominal's at s)."""
        self.s = self.projector.reset(np.asarray(x)[:3], s_guess).s
        if rotor_forces_n is None:
            i, a = self._locate(self.s)
            rotor_forces_n = self.mixer_inverse @ (self._u[i] + a * (self._u[i + 1] - self._u[i]))
        self._rotors_est = np.asarray(rotor_forces_n, dtype=float).copy()

    def step(self, x, rotor_forces_n=None, disturbance: DisturbanceEstimate | None = None) -> RegulatorOutput:
        """One control step for state x (12,); ``rotor_forces_n`` (4,): the rotors' forces
        when this command takes over (used only by lag-aware gains); ``disturbance``: the
        airframe's estimated force model, compensated."""
        x = np.asarray(x, dtype=float)
        proj = self.projector.update(x[:3])
        s = proj.s
        self.s = s
        pt = proj.point
        # Linear interpolation of the tables at s (clamped to the ends).
        i, a = self._locate(s)
        xbar = self._x[i] + a * (self._x[i + 1] - self._x[i])
        K = self._K[i] + a * (self._K[i + 1] - self._K[i])
        u_here = self._u[i] + a * (self._u[i + 1] - self._u[i])
        v = float(self._v[i] + a * (self._v[i + 1] - self._v[i]))
        if self._lead_s > 0.0:
            i, a = self._locate(s + v * self._lead_s)
        ubar = self._u[i] + a * (self._u[i + 1] - self._u[i])
        if disturbance is not None:
            # the compensation's turn rate from the nominal _COMPENSATION_DT_S ahead
            j, b = self._locate(s + max(v, 0.1) * _COMPENSATION_DT_S)
            x_ahead = self._x[j] + b * (self._x[j + 1] - self._x[j])
            t_ahead = float(self._u[j, 0] + b * (self._u[j + 1, 0] - self._u[j, 0]))
            xbar, thrust = compensated_nominal(xbar, float(u_here[0]), self._extra_force(xbar, disturbance),
                                               x_ahead, t_ahead, self._extra_force(x_ahead, disturbance),
                                               _COMPENSATION_DT_S, self._max_turn)
            ubar = ubar.copy()
            ubar[0] += thrust - u_here[0]
            u_here = u_here.copy()
            u_here[0] = thrust
        w = transverse_coordinates(x[:3], pt.frame, pt.position, x, xbar)
        if self._augmented:
            f_act = self._rotors_est if rotor_forces_n is None else np.asarray(rotor_forces_n, float)
            if f_act is None:
                f_act = self.mixer_inverse @ u_here
            u = ubar - K[:, :11] @ w - K[:, 11:] @ (self._mixer @ f_act - u_here)
        else:
            u = ubar - K @ w
        rotors = yaw_then_lift(self.mixer_inverse, u, self._fmax)
        if self._augmented:
            base = self._rotors_est if self._rotors_est is not None else rotors
            self._rotors_est = rotors + (base - rotors) * self._decay
        return RegulatorOutput(s, w, u, rotors, proj.in_tube, s >= self.plan.length_m - 1e-6)
