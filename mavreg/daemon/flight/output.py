"""What leaves the daemon as a command: rotor forces, or body rates and thrust (sans-I/O).

The controllers all compute rotor forces on the paper's model; the supervisor clips them and
records them (:meth:`mavreg.daemon.flight.verbs.Flight.send_rotors`). This module turns
that command into the one message the vehicle takes, by the vehicle file's ``output``:

- ``rotors``: SET_ACTUATOR_CONTROL_TARGET, each rotor's force over its limit;
- ``rates``: SET_ATTITUDE_TARGET with ``type_mask`` 128 (attitude ignored): the wrench of
  those forces realized through a stock autopilot's rate loop and thrust map
  (:mod:`mavreg.model.rate_interface`), at the state predicted to when it takes effect.

In the rates output the torque is realized through the rate loop's inverse as the rotors
would have given it: lagged by the vehicle file's ``rotor_time_constant_s`` (the collective
is lagged by the autopilot's own motors). The plant the controllers see is then the one they
were designed on and that the predictor integrates, the lag-augmented wrench model, whatever
the autopilot in between (docs/autopilots.md).
"""
from __future__ import annotations


from typing import TYPE_CHECKING

import numpy as np

from ...config.vehicle import VehicleParams
from ...model.mixer import Mixer
from ...control.estimation.lag_in_effect import RotorLagInEffect
from ...model.rate_interface import AttitudeLoopCompensation, ThrustMap, rate_command
from ...model.rotor_lag import lag_decay, lag_toward
from ..vehicle import messages as mm
from ..vehicle.peers import VehicleIds

if TYPE_CHECKING:
    from .excitation import RateStep

__all__ = ["RotorOutput", "RateOutput", "command_output"]


class RotorOutput:
    """Rotor forces as actuator controls in [0, 1] (SET_ACTUATOR_CONTROL_TARGET)."""

    kind = "rotors"

    def __init__(self, vehicle: VehicleParams, ids: VehicleIds):
        self._fmax = float(vehicle.max_rotor_thrust_n)
        self._ids = ids

    def message(self, now_s: float, t_s: float, rotor_forces_n: np.ndarray, x: np.ndarray | None,
                excitation: RateStep | None = None):
        """The message for clipped rotor commands (N); ``t_s`` and ``x`` are not needed, and
        there is no rate loop to excite (the supervisor refuses an excitation here)."""
        return mm.actuator_target(int(now_s * 1e6), *self._ids.target, rotor_forces_n / self._fmax)


class RateOutput:
    r"""The wrench of the rotor commands as body rates and a normalized thrust.

    With :math:`(F, \gamma) = M f` (eq 34), the thrust is the thrust map's inverse of F and
    the rates :math:`\omega_c = \omega + \tau_\omega J^{-1}(\gamma - \omega\times J\omega)` at
    the predicted state x (:func:`~mavreg.model.rate_interface.rate_command`), clipped to
    ``max_body_rate_rad_s``. The torque realized is the commanded one through a first-order
    lag of the rotor lag in effect (``rotor_lag``, default the vehicle file's
    ``rotor_time_constant_s``; none when it is 0), stepped by the vehicle time between commands."""

    kind = "rates"

    def __init__(self, vehicle: VehicleParams, ids: VehicleIds, rotor_lag: RotorLagInEffect | None = None):
        p = vehicle.rate_interface
        if p is None:
            raise ValueError("output: rates needs the vehicle file's rate_interface: section")
        self._mixer = Mixer.from_vehicle(vehicle).matrix
        self._map = ThrustMap.from_params(vehicle.mass_kg, p)
        self._inertia = np.asarray(vehicle.inertia_kg_m2, dtype=float)
        yaw_tau = p.rate_time_constant_s if p.yaw_rate_time_constant_s is None else p.yaw_rate_time_constant_s
        self._tau = np.array([p.rate_time_constant_s, p.rate_time_constant_s, yaw_tau], dtype=float)
        self._max_rate = np.asarray(p.max_body_rate_rad_s, dtype=float)
        self._ids = ids
        self.rotor_lag = RotorLagInEffect.of_vehicle(vehicle) if rotor_lag is None else rotor_lag
        self._torque = np.zeros(3)
        self._t_s: float | None = None
        self._attitude_loop = AttitudeLoopCompensation(p.attitude_gain_rad_s)
        self._period_s = 0.0

    def _lagged_torque(self, t_s: float | None, torque: np.ndarray) -> np.ndarray:
        """The torque the lag has reached at ``t_s``: unchanged when no time has passed, the
        command itself with no lag, at the first command or when time went back."""
        lag_s = self.rotor_lag.applied_s
        if lag_s <= 0.0 or t_s is None or self._t_s is None or t_s < self._t_s:
            self._torque = torque.copy()
        elif t_s > self._t_s:
            self._torque = lag_toward(self._torque, torque, lag_decay(t_s - self._t_s, lag_s))
        self._t_s = t_s
        return self._torque

    def command(self, rotor_forces_n: np.ndarray, x: np.ndarray | None,
                t_s: float | None = None, excitation: RateStep | None = None) -> tuple[np.ndarray, float]:
        """(rates (3,) rad/s, normalized thrust) for the rotor commands at state x (None: at
        rest), the torque lagged up to vehicle time ``t_s`` (None: not lagged).
        ``excitation`` (axis, rate rad/s): the identification flight's doublet sends that
        rate on that axis instead (:mod:`mavreg.daemon.flight.excitation`), within the same limits
        and as is: a clean step, not compensated for an autopilot's attitude term (whose
        error still integrates it), as a rate-step measurement sends it."""
        wrench = self._mixer @ np.asarray(rotor_forces_n, dtype=float)
        omega = np.zeros(3) if x is None else np.asarray(x[9:12], dtype=float)
        if t_s is not None and self._t_s is not None and t_s > self._t_s:
            self._period_s = t_s - self._t_s
        rates = rate_command(omega, self._lagged_torque(t_s, wrench[1:]), self._inertia, self._tau)
        rates = np.clip(rates, -self._max_rate, self._max_rate)
        if wrench[0] <= 0.0:
            self._attitude_loop.reset()    # motors idle: ask for no rotation
            return np.zeros(3), self._map.normalized(float(wrench[0]))
        axis = None
        if excitation is not None:
            axis = int(excitation.axis)
            rates[axis] = float(np.clip(excitation.rate_rad_s, -self._max_rate[axis], self._max_rate[axis]))
        if self._attitude_loop.active:
            rates = self._attitude_loop.rates(rates, omega, self._period_s, self._max_rate, as_is=axis)
        return rates, self._map.normalized(float(wrench[0]))

    def message(self, now_s: float, t_s: float, rotor_forces_n: np.ndarray, x: np.ndarray | None,
                excitation: RateStep | None = None):
        rates, thrust = self.command(rotor_forces_n, x, t_s, excitation)
        return mm.rate_target(int(now_s * 1e3) & 0xFFFFFFFF, *self._ids.target, rates, thrust)


def command_output(vehicle: VehicleParams, ids: VehicleIds,
                   rotor_lag: RotorLagInEffect | None = None) -> RotorOutput | RateOutput:
    """The output the vehicle file's ``output`` names, addressed to the vehicle's ``ids`` (read
    at each message: a system id taken from the vehicle's HEARTBEAT applies at once); the rates
    output lags the torque by ``rotor_lag`` (the flight's rotor lag in effect)."""
    if vehicle.output == "rates":
        return RateOutput(vehicle, ids, rotor_lag)
    return RotorOutput(vehicle, ids)
