r"""Recovery controller: from any attitude and speed to a level hold at a safe altitude.

When the maneuver regulator has left its envelope, its linearization no longer holds; this
controller does not linearize. It is the geometric controller on SO(3) of Lee, Leok and
McClamroch ("Geometric tracking control of a quadrotor UAV on SE(3)", CDC 2010), with three
changes for recovery:

- **Desired thrust vector** from a saturated PD on velocity and altitude (NED):
  horizontal velocity command 0 while braking, then back to where braking ended; vertical
  velocity command up to ``safe_altitude_m`` above the take-off point, or to hold the
  highest point reached (a recovery never descends until told to land, :meth:`RecoveryController.land`:
  then down at a set speed to the ground), with conditional integrals for a
  vehicle heavier than the design and for a steady wind. The horizontal acceleration is limited so that the thrust tilts at most
  ``max_tilt_rad`` from vertical:

  .. math:: F_d = m (a_d - g e_3),\qquad b_{3d} = -F_d / |F_d|,\qquad f = -F_d^T R e_3

  (NED, body z down: thrust acts along :math:`-R e_3`). Inverted, :math:`f \le 0`: the
  rotors only turn the vehicle until its thrust points up again.
- **Attitude error** :math:`e_R = \log(R_d^T R)^\vee = \theta n` (body frame), the
  geodesic angle times its axis. Lee's :math:`\tfrac12 (R_d^T R - R^T R_d)^\vee =
  \sin\theta\, n` vanishes when the vehicle is exactly upside down; :math:`\theta n`
  does not, so an inverted vehicle is turned over at once. Torque
  :math:`\tau = -k_R e_R - k_\omega \omega + \omega \times J\omega` (desired rates 0),
  gains from a natural frequency on the design inertia.
- **Allocation that keeps the attitude**: rotor forces must lie in [0, f_max]. The
  collective thrust is given up first (moved to the nearest feasible value); if no
  collective makes the torque feasible, the yaw torque is reduced, then roll and pitch
  are scaled together (the torque's direction is kept).

No Euler angles anywhere: valid at any attitude, inverted included. Pure numbers in and
out; the caller supplies the vehicle time.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...config.envelope import RecoveryParams
from ...config.vehicle import G, VehicleParams
from ...model.mixer import Mixer
from ...model.mixer import collective_first as allocate
from ...model.so3 import attitude_error

__all__ = ["RecoveryController", "RecoveryOutput", "attitude_error", "allocate", "tilt_rad",
           "heading_rad"]

_E3 = np.array([0.0, 0.0, 1.0])


def tilt_rad(R: np.ndarray) -> float:
    """Angle between the body z axis and NED down (0 level, pi inverted)."""
    return math.acos(min(max(float(R[2, 2]), -1.0), 1.0))


def heading_rad(R: np.ndarray) -> float:
    """Heading of the body x axis projected on the horizontal (of body y when x is vertical)."""
    if math.hypot(R[0, 0], R[1, 0]) > 0.3:
        return math.atan2(R[1, 0], R[0, 0])
    return math.atan2(R[1, 1], R[0, 1]) - math.pi / 2.0


@dataclass(frozen=True)
class RecoveryOutput:
    """One step of the recovery controller."""

    rotor_forces_n: np.ndarray
    """Allocated rotor forces, within [0, max_rotor_thrust_n]."""
    thrust_n: float
    """Collective thrust asked before allocation."""
    torque_n_m: np.ndarray
    """Torque asked before allocation."""
    desired_rotation: np.ndarray
    attitude_error_rad: float
    braking: bool
    target_position_m: np.ndarray
    """Where it is going: the altitude target, and the horizontal hold point once braked
    (the current horizontal position while braking)."""


class RecoveryController:
    """Level, brake, climb to a safe altitude, hold (see the module docstring).

    Parameters
    ----------
    vehicle : VehicleParams
        Design mass and inertia (the gains), mixer and rotor limit.
    params : RecoveryParams
    """

    def __init__(self, vehicle: VehicleParams, params: RecoveryParams):
        self.vehicle = vehicle
        self.params = params
        self.mixer_inverse = Mixer.from_vehicle(vehicle).inverse
        self.J = np.array(vehicle.inertia_kg_m2, dtype=float)
        wn = np.array([params.attitude_bandwidth_rad_s] * 2 + [params.yaw_bandwidth_rad_s])
        self.k_R = self.J * wn * wn
        self.k_w = 2.0 * params.attitude_damping * wn * self.J
        self._z_target = 0.0
        self._yaw = 0.0
        self._hold_h: np.ndarray | None = None
        self._bias = 0.0
        self._bias_h = np.zeros(2)
        self._t_last: float | None = None
        self._last_att_err = math.pi
        self._last_rate = math.inf
        self._clipped = False
        self._land_descent_m_s: float | None = None

    @property
    def braking(self) -> bool:
        return self._hold_h is None

    def start(self, position_m, velocity_ned_m_s, R, ground_z_m: float) -> None:
        """Begin a recovery from this state; the take-off point's altitude is ``ground_z_m``."""
        p = np.asarray(position_m, dtype=float)
        self._z_target = min(float(p[2]), ground_z_m - self.params.safe_altitude_m)
        self._yaw = heading_rad(np.asarray(R, dtype=float))
        self._hold_h = None
        self._bias = 0.0
        self._bias_h = np.zeros(2)
        self._t_last = None
        self._last_att_err = math.pi
        self._last_rate = math.inf
        self._clipped = False
        self._land_descent_m_s = None

    def land(self, ground_z_m: float, descent_m_s: float) -> None:
        """From now on, descend at ``descent_m_s`` (braked, level, holding the horizontal
        position as before) until the ground stops it: the altitude target is put a metre
        below the take-off point's altitude ``ground_z_m`` (NED z), so the descent goes on
        through touchdown, where the caller spools the rotors down."""
        if not descent_m_s > 0.0:
            raise ValueError(f"descent speed must be positive, got {descent_m_s!r} m/s")
        self._land_descent_m_s = float(descent_m_s)
        self._z_target = float(ground_z_m) + 1.0

    @property
    def landing(self) -> bool:
        return self._land_descent_m_s is not None

    def _accel(self, p, v, dt: float, integrate: bool) -> np.ndarray:
        prm = self.params
        vh = v[:2]
        if self._hold_h is None and math.hypot(vh[0], vh[1]) < prm.brake_speed_m_s:
            self._hold_h = p[:2].copy()
        if self._hold_h is None:
            vc_h = np.zeros(2)
        else:
            vc_h = prm.position_gain_1_s * (self._hold_h - p[:2])
            n = float(np.linalg.norm(vc_h))
            if n > prm.max_hold_speed_m_s:
                vc_h *= prm.max_hold_speed_m_s / n
        if self._land_descent_m_s is None:
            self._z_target = min(self._z_target, float(p[2]))   # never descend: hold the highest point
            max_down = prm.max_descent_m_s
        else:
            max_down = self._land_descent_m_s
        vc_z = min(max(prm.position_gain_1_s * (self._z_target - p[2]), -prm.max_climb_m_s), max_down)
        ez = vc_z - v[2]
        az = prm.velocity_gain_1_s * ez + self._bias
        if integrate and dt > 0.0 and -prm.max_accel_up_m_s2 < az < prm.max_accel_down_m_s2:
            # conditional integration: never while the vertical demand is saturated
            self._bias = min(max(self._bias + prm.integral_gain_1_s * prm.velocity_gain_1_s * ez * dt,
                                 -prm.max_accel_up_m_s2), prm.max_accel_down_m_s2)
        az = min(max(prm.velocity_gain_1_s * ez + self._bias, -prm.max_accel_up_m_s2), prm.max_accel_down_m_s2)
        eh = vc_h - vh
        lim = math.tan(prm.max_tilt_rad) * (G - az)
        ah = prm.velocity_gain_1_s * eh + self._bias_h
        if integrate and dt > 0.0 and float(np.linalg.norm(ah)) < lim:
            # the same for a steady horizontal force (wind): bounded to half the tilt limit
            self._bias_h = self._bias_h + prm.integral_gain_1_s * prm.velocity_gain_1_s * eh * dt
            nb = float(np.linalg.norm(self._bias_h))
            if nb > 0.5 * lim:
                self._bias_h *= 0.5 * lim / nb
            ah = prm.velocity_gain_1_s * eh + self._bias_h
        n = float(np.linalg.norm(ah))
        if n > lim:
            ah *= lim / n
        return np.array([ah[0], ah[1], az])

    def step(self, t_s: float, position_m, velocity_ned_m_s, R, body_rates_rad_s) -> RecoveryOutput:
        """Rotor forces for the state at vehicle time ``t_s`` (NED position and velocity,
        body-to-NED rotation, body rates)."""
        p = np.asarray(position_m, dtype=float)
        v = np.asarray(velocity_ned_m_s, dtype=float)
        R = np.asarray(R, dtype=float)
        w = np.asarray(body_rates_rad_s, dtype=float)
        dt = 0.0 if self._t_last is None else min(max(t_s - self._t_last, 0.0), 0.1)
        self._t_last = t_s
        m = self.vehicle.mass_kg
        # integrate only once the thrust points roughly where it should and is not clipped
        a_d = self._accel(p, v, 0.0, False)
        F = m * (a_d - G * _E3)
        b3d = -F / np.linalg.norm(F)
        aligned = float(R[:, 2] @ b3d) > math.cos(math.radians(30.0))
        if aligned and not self._clipped:
            a_d = self._accel(p, v, dt, True)
            F = m * (a_d - G * _E3)
            b3d = -F / np.linalg.norm(F)
        b1c = np.array([math.cos(self._yaw), math.sin(self._yaw), 0.0])
        b2d = np.cross(b3d, b1c)
        b2d /= np.linalg.norm(b2d)
        R_d = np.column_stack([np.cross(b2d, b3d), b2d, b3d])
        f = float(-F @ R[:, 2])
        e_R = attitude_error(R_d, R)
        tau = -self.k_R * e_R - self.k_w * w + np.cross(w, self.J * w)
        forces = allocate(f, tau, self.mixer_inverse, self.vehicle.max_rotor_thrust_n)
        self._clipped = abs(float(np.sum(forces)) - f) > 1e-6 * max(1.0, abs(f)) and f > 0.0
        hold = p[:2] if self._hold_h is None else self._hold_h
        self._last_att_err = float(np.linalg.norm(e_R))
        self._last_rate = float(np.linalg.norm(w))
        return RecoveryOutput(forces, f, tau, R_d, self._last_att_err, self._hold_h is None,
                              np.array([hold[0], hold[1], self._z_target]))

    def settled(self, position_m, velocity_ned_m_s, R) -> bool:
        """Braked, slow, near the altitude target, on its desired attitude (level, or tilted
        into a steady wind) and not rotating: judged with the last :meth:`step`'s errors."""
        prm = self.params
        return (self._hold_h is not None and self._last_att_err < prm.settled_attitude_error_rad
                and self._last_rate < prm.settled_rate_rad_s
                and float(np.linalg.norm(velocity_ned_m_s)) < prm.settled_speed_m_s
                and abs(float(position_m[2]) - self._z_target) < prm.settled_altitude_error_m)
