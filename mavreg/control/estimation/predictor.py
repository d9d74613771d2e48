r"""State prediction across the link: where the vehicle will be when a command acts.

A sample stamped ``t`` describes the vehicle at ``t`` (less the estimate's own latency,
which the caller adds to the horizon). A command computed from it reaches the rotors
``H`` later: the downlink, the daemon, the uplink, and the estimate latency. Fed back
without compensation, ``H`` is a pure delay inside the loop; the barrel roll's LQR loses
centimetres at 5 ms and diverges by 20 ms (docs/robustness.md). The predictor removes it:

1. The rotor forces at ``t`` are the first-order lag (time constant :math:`\tau`) of the
   commands that have *acted* before ``t``. The command answering the sample of time
   :math:`t_j` acts from :math:`t_j + H` until the next one takes over, so this is a filter
   over the command history, advanced exactly
   (:math:`f \leftarrow c + (f - c)e^{-\Delta/\tau}`) and kept between calls.
2. From the sample's state, the rigid body of the design model (eqs 1-4, on rotation
   matrices: no Euler singularity) is integrated to :math:`t + H` under the commands
   already sent that act in :math:`[t, t + H)`, the rotor lag included. Each step holds
   the exact mean of the lagged force over the step; attitude uses the exponential map;
   position and velocity are second order.

The result is the state and the rotor forces at the moment the next command takes over:
what the regulator needs (the state for ``w``, the forces for the actuator part of the
lag-augmented gain). The horizon is capped at ``max_horizon_s``.

The integration is one kernel (:mod:`mavreg.control.estimation.predictor_kernel`), the command
history's lag filter and the horizon's segments another
(:mod:`mavreg.control.estimation.command_history_kernel`, the history in preallocated arrays), both
compiled by numba where available: a prediction of ten steps costs a few microseconds.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...config.vehicle import VehicleParams
from .command_history_kernel import advance, prepare
from .predictor_kernel import OUT_SIZE, PARAM_SIZE, predict_into
from .lag_in_effect import RotorLagInEffect

__all__ = ["StatePredictor", "Prediction"]

_NO_TORQUE = np.zeros(6)
"""No torque bias (the kernel's ``tb``)."""

_MAX_PENDING = 4096
"""Commands kept before the acted ones are folded into the rotor state (8 s at 500 Hz)."""


@dataclass(frozen=True)
class Prediction:
    """The vehicle at ``time_s`` (= sample time + horizon)."""

    time_s: float
    horizon_s: float
    x: np.ndarray
    """(12,) design-model state (p, roll pitch yaw, v_body, w_body)."""
    rotation: np.ndarray
    """(3, 3) body-to-NED rotation."""
    rotor_forces_n: np.ndarray
    """(4,) the rotors' lagged forces at ``time_s``."""


class StatePredictor:
    """Predicts the design model across a known delay, with the commands already sent.

    Parameters
    ----------
    vehicle : VehicleParams
        Mass, inertia, arm length, k, rotor limit and the rotor time constant
        (``rotor_time_constant_s``; 0 for ideal rotors).
    max_step_s : float
        Longest integration step (a command switch always starts a new step).
    max_horizon_s : float
        Cap on the prediction horizon.
    rotor_lag : RotorLagInEffect, optional
        The rotor lag in effect, asked at each prediction (default: the vehicle file's; a
        flight's :class:`~mavreg.control.estimation.forecast.Forecaster` gives its own, which
        follows the in-flight estimate).
    """

    def __init__(self, vehicle: VehicleParams, max_step_s: float = 0.002, max_horizon_s: float = 0.1,
                 rotor_lag: RotorLagInEffect | None = None):
        if not (max_step_s > 0 and max_horizon_s >= 0):
            raise ValueError("max_step_s must be > 0 and max_horizon_s >= 0")
        self.mass_kg = float(vehicle.mass_kg)
        self.jx, self.jy, self.jz = (float(j) for j in vehicle.inertia_kg_m2)
        self.l = float(vehicle.arm_length_m)
        self.k = float(vehicle.drag_torque_ratio_m)
        self.fmax = float(vehicle.max_rotor_thrust_n)
        self.rotor_lag = RotorLagInEffect.of_vehicle(vehicle) if rotor_lag is None else rotor_lag
        self.cxy, self.cz = (float(c) for c in vehicle.rotor_drag_n_s_per_m)
        self.cp = float(vehicle.parasitic_drag_n_s2_per_m2)
        self.drag_exponent = float(vehicle.rotor_drag_thrust_exponent)
        self.max_step_s = float(max_step_s)
        self.max_horizon_s = float(max_horizon_s)
        self._prm = np.array([self.mass_kg, self.jx, self.jy, self.jz, self.l, self.k, self.tau,
                              self.cxy, self.cz, self.cp, self.max_step_s, self.drag_exponent])
        assert self._prm.size == PARAM_SIZE
        # The commands not yet fully acted, rows lo:hi (command_history_kernel): the time of
        # the sample each answered, and the four rotor commands; room for twice the most kept.
        self._ct = np.empty(2 * (_MAX_PENDING + 1))
        self._cc = np.empty((self._ct.size, 4))
        self._seg = np.empty((self._ct.size + 2, 5))
        self._lo = self._hi = 0
        self._rot = np.zeros(5)              # the lag filter: its time and the rotor forces then
        self._fresh = True                   # the filter's time is set by the first call
        self._last_delay_s = 0.0

    @property
    def tau(self) -> float:
        """The rotors' time constant the commands are lagged by now (:attr:`rotor_lag`'s
        estimate; a change keeps the rotor state)."""
        return self.rotor_lag.estimate_s

    @property
    def pending(self) -> int:
        """Commands kept (not yet fully acted)."""
        return self._hi - self._lo

    def reset(self, rotor_forces_n=(0.0, 0.0, 0.0, 0.0)) -> None:
        """Forget the command history; the rotors are at ``rotor_forces_n``."""
        self._lo = self._hi = 0
        self._rot[1:5] = [float(v) for v in rotor_forces_n]
        self._fresh = True

    def record(self, t_s: float, rotor_cmd_n) -> None:
        """The command sent in answer to the sample of vehicle time ``t_s`` (clipped as the
        vehicle clips it)."""
        fmax = self.fmax
        c = [0.0 if v < 0.0 else (fmax if v > fmax else float(v)) for v in rotor_cmd_n]
        lo, hi = self._lo, self._hi
        if hi > lo and t_s <= self._ct[hi - 1]:
            self._cc[hi - 1] = c                # a second answer to the same sample replaces the first
        else:
            if hi == self._ct.size:
                self._compact()
                hi = self._hi
            self._ct[hi] = t_s
            self._cc[hi] = c
            self._hi = hi + 1
        if self._hi - self._lo > _MAX_PENDING:
            # Nobody has asked for a prediction for a while (a long preflight): fold the
            # commands that have acted into the rotor state, so the history stays bounded.
            self.rotor_forces(t_s, self._last_delay_s)

    def _compact(self) -> None:
        """Move the live commands to the front of their arrays (doubled if they are full)."""
        lo, hi = self._lo, self._hi
        n = hi - lo
        if n == self._ct.size:
            self._ct = np.concatenate([self._ct, np.empty(n)])
            self._cc = np.concatenate([self._cc, np.empty((n, 4))])
            self._seg = np.empty((self._ct.size + 2, 5))
        else:
            self._ct[:n] = self._ct[lo:hi]
            self._cc[:n] = self._cc[lo:hi]
            self._lo, self._hi = 0, n

    def _start(self, t_s: float, delay_s: float) -> None:
        """The kept filter's time: on the first call, the sample's or the first command's."""
        self._last_delay_s = delay_s
        if self._fresh:               # the rotors were at the reset value until the first command
            self._rot[0] = min(t_s, self._ct[self._lo] + delay_s) if self._hi > self._lo else t_s
            self._fresh = False

    def rotor_forces(self, t_s: float, horizon_s: float):
        """Lagged rotor forces at ``t_s`` from the commands that acted before it (each acts
        ``horizon_s`` after the sample it answered). Advances the kept filter state."""
        self._start(t_s, horizon_s)
        self._lo = advance(self._rot, self._ct, self._cc, self._lo, self._hi, float(t_s), float(horizon_s),
                           self.tau)
        return tuple(self._rot[1:5].tolist())

    def predict(self, t_s: float, x, rotation, horizon_s: float, delay_s: float | None = None,
                external_force_n=(0.0, 0.0, 0.0), thrust_scale: float = 1.0,
                drag_n_s_per_m=None, torque_bias=None) -> Prediction:
        """The state at ``t_s + horizon_s`` from the sample ``x`` (12,) with body-to-NED
        ``rotation`` (3, 3) at ``t_s``. ``horizon_s`` is capped at ``max_horizon_s``.

        ``delay_s`` (default: the horizon) is when commands act after the sample they
        answered; a longer horizon predicts past the first new command (a telemetry gap,
        :meth:`Forecaster.ahead <mavreg.control.estimation.forecast.Forecaster.ahead>`).
        ``external_force_n`` (NED) is a known external force; ``thrust_scale`` the rotors'
        actual per commanded force (the vehicle file's calibration); ``drag_n_s_per_m`` a
        linear body drag (c_xy, c_z) in place of the vehicle file's (an estimate of it);
        ``torque_bias`` (6,) a body torque ``t0 + t1 T`` the airframe adds
        (:mod:`mavreg.control.estimation.torque_bias`; None: none)."""
        out = self.predict_raw(t_s, x, rotation, horizon_s, delay_s, external_force_n, thrust_scale,
                               drag_n_s_per_m, torque_bias)
        H = min(max(float(horizon_s), 0.0), self.max_horizon_s)
        return Prediction(t_s + H, H, out[0:12], out[12:21].reshape(3, 3), out[21:25])

    def predict_raw(self, t_s: float, x, rotation, horizon_s: float, delay_s: float | None = None,
                    external_force_n=(0.0, 0.0, 0.0), thrust_scale: float = 1.0,
                    drag_n_s_per_m=None, torque_bias=None) -> np.ndarray:
        """:meth:`predict` as one array (28,): x (12), R row-major (9), the rotor forces (4),
        and the velocity NED (3) (:data:`~mavreg.control.estimation.predictor_kernel.OUT_SIZE`)."""
        cxy, cz = (self.cxy, self.cz) if drag_n_s_per_m is None else (float(c) for c in drag_n_s_per_m)
        H = min(max(float(horizon_s), 0.0), self.max_horizon_s)
        D = H if delay_s is None else min(max(float(delay_s), 0.0), self.max_horizon_s)
        self._start(t_s, D)
        # the rotors advanced to t_s, then the commands acting in [t_s, t_s + H) as segments
        rot = self._rot
        tau = self._prm[6] = self.tau
        self._lo, n = prepare(self._seg, rot, self._ct, self._cc, self._lo, self._hi, float(t_s), t_s + H, D,
                              tau)
        fext = external_force_n
        out = np.empty(OUT_SIZE)
        predict_into(out, np.asarray(rotation, dtype=float), np.asarray(x, dtype=float), rot[1], rot[2], rot[3],
                     rot[4], self._seg[:n], self._prm, float(thrust_scale), float(fext[0]), float(fext[1]),
                     float(fext[2]), cxy, cz, _NO_TORQUE if torque_bias is None else np.asarray(torque_bias, float))
        return out
