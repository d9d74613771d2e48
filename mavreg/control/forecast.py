"""The state a command will meet: the sample predicted across the link, and the commands sent.

One object that the daemon (and the design-model simulator) hands every sample and every
command it sends, so that the :class:`~mavreg.control.predictor.StatePredictor` always knows
exactly what went out:

- :meth:`Forecaster.update` predicts a sample across the sample-to-actuation delay (or, with
  prediction off, returns it as it is, with the rotor forces the commands imply);
- :meth:`Forecaster.command` turns the rotor forces a controller wants into the commands to
  send (divided by the vehicle file's ``thrust_scale``, clipped as the vehicle clips them)
  and records them.

Pure: numbers in, numbers out; the caller passes vehicle time and the delay.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.vehicle import VehicleParams
from .predictor import StatePredictor

__all__ = ["Forecast", "Forecaster"]


@dataclass(frozen=True)
class Forecast:
    """The vehicle when the next command takes over, and what acts on it."""

    x: np.ndarray
    """(12,) design-model state at the sample time + horizon."""
    rotation: np.ndarray
    rotor_forces_n: np.ndarray
    """(4,) physical rotor forces then (lag and thrust scale included)."""
    horizon_s: float


class Forecaster:
    """Prediction across the link for one vehicle, and the record of the commands sent.

    Parameters
    ----------
    vehicle : VehicleParams
    control_period_s : float
        The integration step of the prediction.
    predict : bool
        Predict across the delay (else the forecast is the sample itself).
    max_horizon_s : float
    """

    def __init__(self, vehicle: VehicleParams, control_period_s: float, predict: bool = True,
                 max_horizon_s: float = 0.1):
        self.vehicle = vehicle
        self.predict = bool(predict)
        self.thrust_scale = float(vehicle.thrust_scale)
        self.period_s = float(control_period_s)
        self.predictor = StatePredictor(vehicle, max_step_s=control_period_s, max_horizon_s=max_horizon_s)

    def reset(self, rotor_forces_n=(0.0, 0.0, 0.0, 0.0)) -> None:
        """Forget the command history (the rotors are at ``rotor_forces_n``, physical)."""
        self.predictor.reset(np.asarray(rotor_forces_n, dtype=float) / self.thrust_scale)

    def update(self, t_s: float, x, rotation, delay_s: float) -> Forecast:
        """A new sample of vehicle time ``t_s``; ``delay_s``: sample-to-actuation delay."""
        x = np.asarray(x, dtype=float)
        R = np.asarray(rotation, dtype=float)
        if not self.predict:
            return Forecast(x, R, self.thrust_scale * np.asarray(self.predictor.rotor_forces(t_s, 0.0)), 0.0)
        p = self.predictor.predict(t_s, x, R, delay_s, thrust_scale=self.thrust_scale)
        return Forecast(p.x, p.rotation, p.rotor_forces_n, p.horizon_s)

    def ahead(self, t_s: float, x, rotation, elapsed_s: float, delay_s: float) -> Forecast | None:
        """The sample of time ``t_s`` predicted ``elapsed_s + delay_s`` ahead (commands act
        ``delay_s`` after the sample they answer): the state a command sent ``elapsed_s``
        after that sample would meet. None past the prediction horizon."""
        horizon = elapsed_s + delay_s
        if not self.predict or horizon > self.predictor.max_horizon_s:
            return None
        p = self.predictor.predict(t_s, x, rotation, horizon, delay_s=delay_s,
                                   thrust_scale=self.thrust_scale)
        return Forecast(p.x, p.rotation, p.rotor_forces_n, p.horizon_s)

    def command(self, t_s: float, rotor_forces_n) -> np.ndarray:
        """Rotor commands (N, before the vehicle's thrust scale) that give ``rotor_forces_n``,
        clipped to [0, max]; recorded as answering the sample of time ``t_s``."""
        want = np.asarray(rotor_forces_n, dtype=float) / self.thrust_scale
        cmd = np.clip(want, 0.0, self.vehicle.max_rotor_thrust_n)
        self.predictor.record(t_s, cmd)
        return cmd
