r"""A stock autopilot's rate-and-thrust interface: its thrust map and its rate loop's inverse.

Stock autopilots (PX4 OFFBOARD, ArduCopter GUIDED) take body rates and a normalized
collective thrust, not rotor forces; their own rate loop turns the rates into torques. mavreg
keeps designing on the paper's wrench model and realizes its wrench :math:`(F, \gamma)`
through that interface (docs/autopilots.md):

- the collective by the inverse of the thrust map
  :math:`F = F_{max}\,((1 - e)\,t + e\,t^2)`, :math:`t \in [0, 1]`;
- the torque by the inverse of the rate loop's model. With the loop's response
  :math:`\dot\omega = (\omega_c - \omega)/\tau_\omega` (its pure delay is predicted
  across, as the link's is), the rigid body :math:`J\dot\omega = \gamma - \omega\times J\omega`
  gets the torque :math:`\gamma` exactly when

  .. math::
      \omega_c = \omega + \tau_\omega J^{-1}(\gamma - \omega \times J \omega),

  evaluated at the state predicted to the instant the command takes effect.

Pure functions on numbers (numpy or floats); no I/O.
"""
from __future__ import annotations

import math

import numpy as np

from ..config.vehicle import G, RateInterfaceParams

__all__ = ["ThrustMap", "rate_command", "rate_response_rhs", "AttitudeLoopCompensation"]


class ThrustMap:
    r"""Newtons to the autopilot's normalized thrust and back.

    Parameters
    ----------
    mass_kg : float
        The mass the hover thrust holds.
    hover_thrust : float
        Normalized thrust of a level hover, :math:`t_h \in (0, 1)`.
    thrust_expo : float
        The map's curvature e in [0, 1].
    """

    def __init__(self, mass_kg: float, hover_thrust: float, thrust_expo: float = 0.0):
        if not 0.0 < hover_thrust < 1.0 or not 0.0 <= thrust_expo <= 1.0:
            raise ValueError(f"hover_thrust must be in (0, 1) and thrust_expo in [0, 1], "
                             f"got {hover_thrust}, {thrust_expo}")
        self.expo = float(thrust_expo)
        self.max_thrust_n = mass_kg * G / self._shape(hover_thrust)
        """F_max: the collective at t = 1."""

    @classmethod
    def from_params(cls, mass_kg: float, p: RateInterfaceParams) -> "ThrustMap":
        return cls(mass_kg, p.hover_thrust, p.thrust_expo)

    def _shape(self, t):
        return (1.0 - self.expo) * t + self.expo * t * t

    def thrust_n(self, t):
        """The collective (N) at normalized thrust t."""
        return self.max_thrust_n * self._shape(t)

    def normalized(self, thrust_n: float) -> float:
        """The normalized thrust in [0, 1] that gives ``thrust_n`` (clipped to the map's range;
        a non-finite force gives NaN, which no message builder accepts)."""
        y = thrust_n / self.max_thrust_n
        if not math.isfinite(y):
            return math.nan
        y = min(max(y, 0.0), 1.0)
        e = self.expo
        if e < 1e-9 or y == 0.0:
            return y
        # the root in [0, 1] of e t^2 + (1 - e) t - y = 0, in the cancellation-free form
        b = 1.0 - e
        return min(2.0 * y / (b + math.sqrt(b * b + 4.0 * e * y)), 1.0)


def rate_command(omega, torque_n_m, inertia_kg_m2, time_constant_s) -> np.ndarray:
    r"""The rate command :math:`\omega_c = \omega + \tau J^{-1}(\gamma - \omega\times J\omega)`
    that makes a first-order rate loop of time constant :math:`\tau` give the rigid body of
    diagonal inertia J the torque :math:`\gamma` (all body frame, (3,)); :math:`\tau` one for
    every axis or one per axis (3,)."""
    w = np.asarray(omega, dtype=float)
    J = np.asarray(inertia_kg_m2, dtype=float)
    gyro = np.cross(w, J * w)
    return w + time_constant_s * (np.asarray(torque_n_m, dtype=float) - gyro) / J


def rate_response_rhs(omega, omega_cmd, time_constant_s: float):
    r""":math:`\dot\omega = (\omega_c - \omega)/\tau`: the rate loop's model (delay excluded)."""
    return (np.asarray(omega_cmd) - np.asarray(omega)) / time_constant_s


class AttitudeLoopCompensation:
    r"""Rates to send to an autopilot that adds an attitude loop on the integral of its rate
    commands, so that the rate it aims for is the one wanted.

    ArduCopter's rate target for body rates :math:`\omega_s` is
    :math:`\omega_s + K e`, with :math:`\dot e = \omega_s - \omega` (small angles: the
    attitude the integral of the commands leads to, less the attitude flown). Keeping the same
    :math:`e` and sending :math:`\omega_s = \omega^* - K e` makes that target
    :math:`\omega^*`. :math:`e` is clipped to ``max_error_rad`` per axis and restarts at 0
    with :meth:`reset` (the autopilot resets its target on the ground).

    Parameters
    ----------
    gain_rad_s : (3,) array_like
        K per body axis (0: no such loop; nothing is changed).
    max_error_rad : float
    """

    def __init__(self, gain_rad_s, max_error_rad: float = 0.3):
        self.gain = np.asarray(gain_rad_s, dtype=float)
        self.max_error_rad = float(max_error_rad)
        self.error = np.zeros(3)

    @property
    def active(self) -> bool:
        return bool(np.any(self.gain > 0.0))

    def reset(self) -> None:
        self.error = np.zeros(3)

    def rates(self, wanted, omega, dt_s: float, limit=np.inf, as_is=None) -> np.ndarray:
        """The rates to send (within +-``limit``) for ``wanted`` (3,), the body rates now
        ``omega`` (3,), and the time ``dt_s`` this command will be held. ``as_is`` (an axis
        index, or None): that axis is sent as wanted, uncompensated (an identification step,
        which should reach the autopilot as a clean step); its error integrates as ever."""
        send = np.clip(np.asarray(wanted, dtype=float) - self.gain * self.error, -limit, limit)
        if as_is is not None:
            cap = float(np.broadcast_to(limit, (3,))[as_is])
            send[as_is] = min(max(float(wanted[as_is]), -cap), cap)
        step = dt_s * (send - np.asarray(omega, dtype=float))
        self.error = np.clip(self.error + step, -self.max_error_rad, self.max_error_rad)
        return send
