"""The state a command will meet: the sample predicted across the link, and the commands sent.

One object that the daemon (and the design-model simulator) hands every sample and every
command it sends, so that the :class:`~mavreg.control.estimation.predictor.StatePredictor` always knows
exactly what went out:

- :meth:`Forecaster.update` predicts a sample across the sample-to-actuation delay (or, with
  prediction off, returns it as it is, with the rotor forces the commands imply);
- :meth:`Forecaster.command` turns the rotor forces a controller wants into the commands to
  send (divided by the thrust scale, clipped as the vehicle clips them) and records them.

With a :class:`~mavreg.control.estimation.disturbance.DisturbanceObserver` (``disturbance.enabled`` in the
controller file), every sample, while :attr:`Forecaster.observing`, is also compared with its
prediction from the previous one (velocity, and body rates for the torque part); the
observer's estimate (drag, constant force, thrust scale, torque bias) then enters every
prediction and the thrust scale every command, and
:attr:`Forecaster.disturbance` hands it to the regulator's compensation.

Pure: numbers in, numbers out; the caller passes vehicle time and the delay.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...config.defaults import MAX_PREDICTION_S
from ...config.disturbance import DisturbanceParams
from ...config.vehicle import VehicleParams
from ...model.mixer import mixer_matrix
from .disturbance import DisturbanceEstimate, DisturbanceObserver
from .predictor import StatePredictor
from .lag_in_effect import RotorLagInEffect

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
    disturbance : DisturbanceParams, optional
        The disturbance observer's settings; None or not ``enabled``: no observer.
    """

    def __init__(self, vehicle: VehicleParams, control_period_s: float, predict: bool = True,
                 max_horizon_s: float = MAX_PREDICTION_S, disturbance: DisturbanceParams | None = None):
        self.vehicle = vehicle
        self.predict = bool(predict)
        self.period_s = float(control_period_s)
        self.observer = (DisturbanceObserver(disturbance, vehicle)
                         if disturbance is not None and disturbance.enabled else None)
        self.rotor_lag = RotorLagInEffect.of_vehicle(vehicle, None if self.observer is None else self.observer.lag)
        """The rotor lag in effect (the file's, or the observer's estimate of it): the predictor,
        the regulator and the rates output ask it; nobody keeps a copy."""
        self.predictor = StatePredictor(vehicle, max_step_s=control_period_s, max_horizon_s=max_horizon_s,
                                        rotor_lag=self.rotor_lag)
        self._torque_rows = mixer_matrix(vehicle.arm_length_m, vehicle.drag_torque_ratio_m)[1:4]
        """The rotor forces' body torques (the mixer's rows 1-3)."""
        self.observing = False
        """Whether samples feed the observer (the supervisor sets it: airborne phases only)."""
        self._previous = None

    @property
    def disturbance(self) -> DisturbanceEstimate | None:
        """The observer's estimate as the compensation applies it (rate-limited; None
        without an observer)."""
        return self.observer.applied if self.observer is not None else None

    @property
    def thrust_scale(self) -> float:
        """Thrust per unit commanded that the commands allow for: the observer's (applied)
        estimate, else the vehicle file's."""
        return self.observer.applied.thrust_scale if self.observer is not None else float(self.vehicle.thrust_scale)

    def _model(self) -> dict:
        """The predictor's keyword arguments for the airframe as currently known."""
        if self.observer is None:
            return {"thrust_scale": float(self.vehicle.thrust_scale)}
        est = self.observer.estimate
        model = {"thrust_scale": est.thrust_scale, "external_force_n": est.force_ned_n,
                 "drag_n_s_per_m": est.drag_n_s_per_m}
        if self.observer.torque is not None:
            model["torque_bias"] = est.torque_bias
        return model

    def reset(self, rotor_forces_n=(0.0, 0.0, 0.0, 0.0)) -> None:
        """Forget the command history (the rotors are at ``rotor_forces_n``, physical)."""
        self.predictor.reset(np.asarray(rotor_forces_n, dtype=float) / self.thrust_scale)
        self._previous = None

    def _observe(self, t_s: float, x, R, delay_s: float) -> None:
        """Feed the observer this sample's velocity against its prediction from the last one."""
        previous, self._previous = self._previous, (t_s, x, R)
        if previous is None or not self.observing:
            return
        t0, x0, R0 = previous
        h = t_s - t0
        obs = self.observer
        if not 0.0 < h <= obs.params.max_sample_gap_s:
            obs.sample_gap()
            return
        model = self._model()
        f0 = self.predictor.rotor_forces(t0, delay_s)
        p = self.predictor.predict_raw(t0, x0, R0, h, delay_s=delay_s, **model)
        thrust = 0.5 * (sum(f0) + float(p[21] + p[22] + p[23] + p[24]) / model["thrust_scale"])
        obs.update(h, R0, R0 @ x0[6:9], thrust, R @ x[6:9] - p[25:28])
        # the torque and lag parts: the body rates against theirs, at the physical collective
        rate_innovation = x[9:12] - p[9:12]
        obs.update_torque(h, thrust * model["thrust_scale"], rate_innovation, x[9:12])
        if obs.lag is not None:
            dtorque = self._torque_rows @ (p[21:25] - model["thrust_scale"] * np.asarray(f0))
            obs.update_lag(h, dtorque, rate_innovation, x[9:12])

    def update(self, t_s: float, x, rotation, delay_s: float) -> Forecast:
        """A new sample of vehicle time ``t_s``; ``delay_s``: sample-to-actuation delay."""
        x = np.asarray(x, dtype=float)
        R = np.asarray(rotation, dtype=float)
        if self.observer is not None:
            self._observe(t_s, x, R, delay_s)
        if not self.predict:
            return Forecast(x, R, self.thrust_scale * np.asarray(self.predictor.rotor_forces(t_s, 0.0)), 0.0)
        p = self.predictor.predict(t_s, x, R, delay_s, **self._model())
        return Forecast(p.x, p.rotation, p.rotor_forces_n, p.horizon_s)

    def ahead(self, t_s: float, x, rotation, elapsed_s: float, delay_s: float) -> Forecast | None:
        """The sample of time ``t_s`` predicted ``elapsed_s + delay_s`` ahead (commands act
        ``delay_s`` after the sample they answer): the state a command sent ``elapsed_s``
        after that sample would meet. None past the prediction horizon."""
        horizon = elapsed_s + delay_s
        if not self.predict or horizon > self.predictor.max_horizon_s:
            return None
        p = self.predictor.predict(t_s, x, rotation, horizon, delay_s=delay_s, **self._model())
        return Forecast(p.x, p.rotation, p.rotor_forces_n, p.horizon_s)

    def command(self, t_s: float, rotor_forces_n) -> np.ndarray:
        """Rotor commands (N, before the vehicle's thrust scale) that give ``rotor_forces_n``,
        clipped to [0, max]; recorded as answering the sample of time ``t_s``."""
        want = np.asarray(rotor_forces_n, dtype=float) / self.thrust_scale
        cmd = np.clip(want, 0.0, self.vehicle.max_rotor_thrust_n)
        self.predictor.record(t_s, cmd)
        return cmd
