r"""Point-stabilizing LQR at hover, and smooth reference ramps for take-off, hold and landing.

The gain comes from the same design model as the maneuver regulator
(:class:`mavreg.model.quadrotor.QuadrotorModel`, paper eqs 6-17), linearized at a level
hover with the target yaw:

.. math::
    u = u_{ref} - K (x - x_{ref}),\qquad K = R^{-1} B^T P,\qquad
    A^T P + P A - P B R^{-1} B^T P + Q = 0,

with the yaw error wrapped to (-pi, pi]. The reference ``x_ref`` is either a fixed hover
point or a point of a :class:`Ramp`: a degree-7 polynomial in time per axis (position
and yaw) joining (p0, v0, a0) to (p1, v1, a1) with zero jerk at both ends, so position,
velocity, acceleration and jerk are continuous (C^3) across chained ramps. The ramp's acceleration
(less an estimated disturbance force) is fed forward as the roll/pitch and thrust that produce
it, its jerk as small-angle rates, so the hover LQR tracks it closely.
Its duration is the shortest that keeps speed and acceleration inside the limits of
:class:`HoverParams`, which keeps every rotor well away from saturation.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import solve_continuous_are

from ...accel import use_compiled
from ...config.vehicle import G, VehicleParams
from ...model.linearize import model_jacobians
from ...model.mixer import Mixer, yaw_then_lift
from ...model.quadrotor import NX, QuadrotorModel
from ...model.rotation import rpy_to_matrix, wrap_angle
from ...model.rotation_kernel import wrap
from . import hover_kernel as hk
from ..estimation.torque_bias import allocated_less_bias

__all__ = ["HoverParams", "HoverController", "HoverOutput", "Ramp", "plan_ramp", "hold_ramp"]


@dataclass(frozen=True)
class HoverParams:
    """Weights and reference limits of the hover controller (SI units)."""

    q: tuple[float, ...] = (20.0, 20.0, 30.0, 4.0, 4.0, 4.0, 6.0, 6.0, 8.0, 0.5, 0.5, 0.5)
    """Diagonal of Q over x = (p, roll pitch yaw, v_body, w_body)."""
    r: tuple[float, ...] = (0.1, 4.0, 4.0, 1.0)
    """Diagonal of R over u = (f, g1, g2, g3). The defaults are the controller file's
    (:attr:`mavreg.config.controller.ControllerParams.hover_r_input`, which says why)."""
    max_speed_m_s: float = 2.5
    """Largest reference speed of a take-off, transfer or landing ramp."""
    max_accel_m_s2: float = 1.0
    """Largest reference acceleration of a ramp (keeps rotors far from saturation)."""
    max_yaw_rate_rad_s: float = 0.8
    """Largest reference yaw rate of a ramp."""

    @classmethod
    def from_controller(cls, controller) -> "HoverParams":
        """The weights of a controller file (``hover_q``, ``hover_r_input``), the default
        reference limits; None: the defaults."""
        if controller is None:
            return cls()
        return cls(q=tuple(controller.hover_q), r=tuple(controller.hover_r_input))

    def __post_init__(self):
        if len(self.q) != NX or len(self.r) != 4:
            raise ValueError("HoverParams: q needs 12 weights and r needs 4")
        if min(self.q) < 0 or min(self.r) <= 0:
            raise ValueError("HoverParams: q must be >= 0 and r > 0")


@dataclass(frozen=True)
class HoverOutput:
    """One step of the hover controller."""

    u: np.ndarray
    """(f, g1, g2, g3) commanded wrench."""
    rotor_forces_n: np.ndarray
    """Rotor forces f1..f4 of ``u``; where one would pull, the yaw torque gives way, then all
    four are lifted (:func:`~mavreg.model.mixer.yaw_then_lift`); not clipped at the top."""
    error: np.ndarray
    """x - x_ref, yaw wrapped (12,)."""


_DEG = 7


def _septic(y0: float, v0: float, a0: float, y1: float, v1: float, a1: float, T: float) -> np.ndarray:
    """Coefficients c0..c7 of y(t) = sum c_k t^k with the given value, velocity and
    acceleration at 0 and T and zero jerk at both ends (so the feed-forward body rates of
    chained ramps are continuous too)."""
    c = np.zeros(_DEG + 1)
    c[0], c[1], c[2], c[3] = y0, v0, a0 / 2.0, 0.0
    rows, rhs = [], []
    for order, target in ((0, y1), (1, v1), (2, a1), (3, 0.0)):
        row = np.zeros(4)
        known = 0.0
        for k in range(_DEG + 1):
            coef = _falling(k, order) * T ** (k - order) if k >= order else 0.0
            if k < 4:
                known += coef * c[k]
            else:
                row[k - 4] = coef
        rows.append(row)
        rhs.append(target - known)
    c[4:] = np.linalg.solve(np.array(rows), np.array(rhs))
    return c


def _falling(k: int, order: int) -> float:
    """k (k-1) ... (k-order+1): the factor of the order-th derivative of t^k."""
    out = 1.0
    for i in range(order):
        out *= k - i
    return out


_DERIV = np.array([[[_falling(k, order) if k >= order else 0.0 for k in range(_DEG + 1)]
                    for order in range(4)]])
"""(1, 4, 8): factor of t^(k-order) in the order-th derivative of c_k t^k."""
_SHIFT = np.array([[k - order if k >= order else 0 for k in range(_DEG + 1)] for order in range(4)])


def _poly_eval_many(c: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """(len(ts), rows of c, 4): value and first three derivatives of each polynomial row of
    ``c`` (shape (rows, 8)) at each time."""
    ts = np.asarray(ts, dtype=float)
    powers = ts[:, None, None] ** _SHIFT[None]                     # (T, 4, 8)
    terms = _DERIV[None] * powers[:, None, :, :] * c[None, :, None, :]   # (T, rows, 4, 8)
    return terms.sum(axis=-1)


@dataclass(frozen=True)
class Ramp:
    """A C^3 reference from (p0, v0, a0, yaw0) to (p1, v1, a1, yaw1) over ``duration_s``.

    Before t=0 it holds the start, after ``duration_s`` it continues at the end velocity
    (a hold when ``v1`` is zero).
    """

    coeffs: np.ndarray
    """(4, 8): x, y, z and yaw polynomials (degree 7)."""
    duration_s: float
    end_position_m: np.ndarray
    end_velocity_m_s: np.ndarray
    end_yaw_rad: float

    def sample(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
        """(position, velocity, acceleration) NED, yaw and yaw rate at ramp time ``t_s``."""
        p, v, a, _, yaw, yaw_rate = self.sample_with_jerk(t_s)
        return p, v, a, yaw, yaw_rate

    def sample_with_jerk(self, t_s: float):
        """(position, velocity, acceleration, jerk) NED, yaw and yaw rate at ramp time ``t_s``."""
        if t_s >= self.duration_s:
            dt = t_s - self.duration_s
            return (self.end_position_m + self.end_velocity_m_s * dt, self.end_velocity_m_s.copy(),
                    np.zeros(3), np.zeros(3), self.end_yaw_rad, 0.0)
        vals = _poly_eval_many(self.coeffs, np.array([max(t_s, 0.0)]))[0]   # (4 rows, 4 derivs)
        return (vals[:3, 0], vals[:3, 1], vals[:3, 2], vals[:3, 3], float(vals[3, 0]),
                float(vals[3, 1]))

    def finished(self, t_s: float) -> bool:
        return t_s >= self.duration_s


def plan_ramp(p0, v0, yaw0: float, p1, v1, yaw1: float, params: HoverParams,
              a0=None, a1=None, min_duration_s: float = 0.5) -> Ramp:
    """Shortest degree-7 ramp that respects the speed, acceleration and yaw-rate limits.

    The yaw goes the short way round. The duration is searched on a geometric grid
    (5% steps), checking the limits on 60 samples, and never shorter than ``min_duration_s``.
    Durations whose velocity reverses against the direction of travel are skipped so
    that a ramp with a moving end never backs up.
    """
    p0, v0, p1, v1 = (np.asarray(a, dtype=float) for a in (p0, v0, p1, v1))
    a0 = np.zeros(3) if a0 is None else np.asarray(a0, dtype=float)
    a1 = np.zeros(3) if a1 is None else np.asarray(a1, dtype=float)
    yaw1_unwrapped = yaw0 + float(wrap_angle(yaw1 - yaw0))
    travel = p1 - p0
    dist = float(np.linalg.norm(travel))
    direction = travel / dist if dist > 1e-9 else np.zeros(3)
    vmax = max(params.max_speed_m_s, float(np.linalg.norm(v0)), float(np.linalg.norm(v1)))
    T = min_duration_s
    for _ in range(400):
        coeffs = np.vstack([_septic(p0[i], v0[i], a0[i], p1[i], v1[i], a1[i], T) for i in range(3)]
                           + [_septic(yaw0, 0.0, 0.0, yaw1_unwrapped, 0.0, 0.0, T)])
        ts = np.linspace(0.0, T, 60)
        vals = _poly_eval_many(coeffs, ts)   # (60, 4 rows, 4 derivatives)
        speed = np.linalg.norm(vals[:, :3, 1], axis=1)
        accel = np.linalg.norm(vals[:, :3, 2], axis=1)
        yaw_rate = np.abs(vals[:, 3, 1])
        along = vals[:, :3, 1] @ direction
        ok = (speed.max() <= vmax * 1.001 and accel.max() <= params.max_accel_m_s2
              and yaw_rate.max() <= params.max_yaw_rate_rad_s and along.min() >= -0.05)
        if ok:
            break
        T *= 1.05
    else:
        raise ValueError("plan_ramp: no duration meets the ramp limits")
    return Ramp(coeffs, T, p1.copy(), v1.copy(), float(wrap_angle(yaw1_unwrapped)))


def hold_ramp(position_m, yaw_rad: float) -> Ramp:
    """A ramp that is a fixed hover point (zero duration)."""
    p = np.asarray(position_m, dtype=float)
    coeffs = np.zeros((4, _DEG + 1))
    coeffs[:3, 0] = p
    coeffs[3, 0] = yaw_rad
    return Ramp(coeffs, 0.0, p.copy(), np.zeros(3), float(yaw_rad))


@dataclass
class HoverController:
    """LQR about level hover; gains computed once per yaw (K does depend on yaw).

    ``compiled``: step by the compiled kernels (:mod:`mavreg.control.controllers.hover_kernel`, the same
    outputs to rounding) or by the numpy step, the reference; None (default): compiled where
    numba is (:data:`mavreg.accel.ACCELERATED`).
    """

    vehicle: VehicleParams
    params: HoverParams = field(default_factory=HoverParams)
    compiled: bool | None = None

    def __post_init__(self):
        self._compiled = use_compiled(self.compiled, "hover step")
        self.model = QuadrotorModel.from_vehicle(self.vehicle)
        self.mixer = Mixer.from_vehicle(self.vehicle)
        self._gains: dict[float, np.ndarray] = {}
        self._minv = np.ascontiguousarray(self.mixer.inverse, dtype=float).ravel()
        self._ramp = self._ramp_pack = self._ramp_v = self._coeffs = None
        self._no_torque = np.zeros(6)

    def gain(self, yaw_rad: float) -> np.ndarray:
        """K (4, 12) of the LQR linearized at level hover with yaw ``yaw_rad`` (cached per 1e-3 rad)."""
        key = round(wrap(float(yaw_rad)), 3)          # wrapped to (-pi, pi], scalar
        K = self._gains.get(key)
        if K is None:
            K = self._gains[key] = self.design_loop(key)[2]
        return K

    def design_loop(self, yaw_rad: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A (12, 12), B (12, 4), K (4, 12)): the design model linearized at level hover with
        yaw ``yaw_rad`` (in time, ideal rotors) and the LQR gain on it (not cached)."""
        x0 = np.zeros(NX)
        x0[5] = yaw_rad
        A, B = model_jacobians(self.model.f, x0, self.model.hover_input())
        Q = np.diag(self.params.q)
        R = np.diag(self.params.r)
        P = solve_continuous_are(A, B, Q, R)
        return A, B, np.linalg.solve(R, B.T @ P)

    def reference(self, ramp: Ramp, t_s: float, disturbance=None) -> tuple[np.ndarray, np.ndarray]:
        """(x_ref (12,), u_ref (4,)) of a ramp at time ``t_s``: the attitude and thrust that give
        the ramp's acceleration, its velocity in that body frame, and its jerk as small-angle
        rates. A :class:`~mavreg.control.estimation.disturbance.DisturbanceEstimate` is fed forward too:
        the attitude and thrust are those of ``a - d/m``, with the estimated drag taken at that
        attitude (the hover model has none of its own)."""
        p, v, a, j, yaw, yaw_rate = ramp.sample_with_jerk(t_s)
        m = self.vehicle.mass_kg
        roll, pitch, thrust, R = self._attitude_for(np.asarray(a, dtype=float), yaw)
        if disturbance is not None:
            for _ in range(3):           # the drag depends on the attitude it tilts (contracts 10x a pass)
                d = disturbance.extra_force_ned(R, v, (0.0, 0.0))
                roll, pitch, thrust, R = self._attitude_for(np.asarray(a, dtype=float) - d / m, yaw)
        c, s = np.cos(yaw), np.sin(yaw)
        j_b = np.array([c * j[0] + s * j[1], -s * j[0] + c * j[1], j[2]])
        x_ref = np.zeros(NX)
        x_ref[0:3] = p
        x_ref[3:6] = roll, pitch, yaw
        x_ref[6:9] = R.T @ np.asarray(v, dtype=float)
        x_ref[9] = j_b[1] / G       # rates of the tilt, small-angle
        x_ref[10] = -j_b[0] / G
        x_ref[11] = yaw_rate
        u_ref = np.array([m * thrust, 0.0, 0.0, 0.0])
        return x_ref, u_ref

    @staticmethod
    def _attitude_for(a_ned: np.ndarray, yaw: float):
        """(roll, pitch, thrust per unit mass, R) whose thrust gives acceleration ``a_ned`` at
        ``yaw``: exact, not small-angle (a wind's drag can ask for 20 deg and 5 % more thrust).
        The body z axis in the heading frame is (s_th c_ph, -s_ph, c_th c_ph)."""
        c, s = np.cos(yaw), np.sin(yaw)
        f = a_ned - np.array([0.0, 0.0, G])
        thrust = float(np.linalg.norm(f))
        b3 = -f / thrust
        b3_h = np.array([c * b3[0] + s * b3[1], -s * b3[0] + c * b3[1], b3[2]])
        roll = float(np.arcsin(np.clip(-b3_h[1], -1.0, 1.0)))   # roll tilts the thrust right (east at yaw 0)
        pitch = float(np.arctan2(b3_h[0], b3_h[2]))             # pitch nose-down accelerates forward
        return roll, pitch, thrust, rpy_to_matrix(roll, pitch, yaw)

    def step(self, x: np.ndarray, ramp: Ramp, t_s: float, disturbance=None) -> HoverOutput:
        """Control ``u`` for state ``x`` (12,) following ``ramp`` at ramp time ``t_s``, with an
        estimated ``disturbance`` fed forward (see :meth:`reference`; its torque bias is taken
        from the torques the rotors are asked for, :mod:`mavreg.control.estimation.torque_bias`)."""
        if self._compiled:
            return self._step_compiled(x, ramp, t_s, disturbance)
        x_ref, u_ref = self.reference(ramp, t_s, disturbance)
        e = self.error(x, x_ref)
        u = self.tilt_compensated(u_ref - self.gain(x_ref[5]) @ e, x, x_ref)
        fmax = self.vehicle.max_rotor_thrust_n
        if disturbance is not None and any(disturbance.torque_bias):    # the rotors give u less the bias
            rotors = allocated_less_bias(yaw_then_lift, self.mixer.inverse, u, fmax, disturbance.torque_bias)
        else:
            rotors = yaw_then_lift(self.mixer.inverse, u, fmax)
        return HoverOutput(u=u, rotor_forces_n=rotors, error=e)

    @staticmethod
    def error(x, x_ref) -> np.ndarray:
        r"""``x - x_ref`` (12,), the angles wrapped, and the velocity error taken in the
        reference's body frame: :math:`e_v = \bar R^T (R v_b - \bar R \bar v_b)` (NED velocity
        error seen from the reference attitude :math:`\bar R`), not :math:`v_b - \bar v_b`.

        The gain is designed at hover, where the two agree. Along a ramp they do not: the
        measured body velocity turns with every attitude error, :math:`\delta\theta \times v`,
        a coupling the hover model does not have. In a 2.2 m/s take-off climb it fed the
        estimate's 0.3 deg attitude noise into the velocity error at 4 cm/s a degree and the
        roll rang until the rate bound fired at 9 m. Seen from the reference the error obeys
        the hover linearization at any constant velocity."""
        e = np.asarray(x, dtype=float) - x_ref
        e[3:6] = wrap_angle(e[3:6])
        v_ned = rpy_to_matrix(*x[3:6]) @ np.asarray(x[6:9], dtype=float)
        e[6:9] = rpy_to_matrix(*x_ref[3:6]).T @ v_ned - x_ref[6:9]
        return e

    @staticmethod
    def tilt_compensated(u, x, x_ref) -> np.ndarray:
        r"""``u`` with its collective divided by :math:`\cos\delta = \bar b_3^T b_3`, the cosine of
        the tilt of the body z axis from the reference's (bounded below by
        :data:`~mavreg.control.controllers.hover_kernel.MIN_TILT_COS`), so that the thrust along the
        reference's axis is what the LQR asked for.

        The gain is designed at hover, where tilting costs lift only to second order. In a
        6 m/s wind the feedback tilts the vehicle 25 deg into it before the observer's
        estimate has caught up (it learns only once airborne, and the compensation follows
        at 2.5 N/s): 10 % of the lift went, and the vehicle sank back onto the ground tilted
        (a rate error at lift-off in every 6 m/s flight of the robustness campaign)."""
        u = np.array(u, dtype=float)
        b3 = rpy_to_matrix(*x[3:6])[:, 2]
        b3_ref = rpy_to_matrix(*x_ref[3:6])[:, 2]
        u[0] /= max(float(b3 @ b3_ref), hk.MIN_TILT_COS)
        return u

    def _step_compiled(self, x, ramp: Ramp, t_s: float, disturbance) -> HoverOutput:
        """:meth:`step` by the kernels of :mod:`mavreg.control.controllers.hover_kernel`."""
        if ramp is not self._ramp:
            self._ramp = ramp
            self._ramp_pack = np.array([ramp.duration_s, *ramp.end_position_m, ramp.end_yaw_rad, 0.0])
            self._ramp_v = np.ascontiguousarray(ramp.end_velocity_m_s, dtype=float)
            self._coeffs = np.ascontiguousarray(ramp.coeffs, dtype=float)
        ref = np.empty(hk.REF_SIZE)
        if disturbance is None:
            hk.reference(ref, self._coeffs, float(t_s), self._ramp_pack, self._ramp_v, False, 0.0, 0.0, 0.0, 0.0,
                         0.0, float(self.vehicle.mass_kg))
        else:
            (cxy, cz), (fx, fy, fz) = disturbance.drag_n_s_per_m, disturbance.force_ned_n
            hk.reference(ref, self._coeffs, float(t_s), self._ramp_pack, self._ramp_v, True, float(cxy), float(cz),
                         float(fx), float(fy), float(fz), float(self.vehicle.mass_kg))
        out = np.empty(hk.OUT_SIZE)
        tb = self._no_torque if disturbance is None else np.array(disturbance.torque_bias, dtype=float)
        hk.feedback(out, np.asarray(x, dtype=float), ref, self.gain(ref[5]), self._minv,
                    float(self.vehicle.max_rotor_thrust_n), tb)
        return HoverOutput(u=out[0:4], rotor_forces_n=out[4:8], error=out[8:20])
