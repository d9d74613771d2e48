"""A closed-loop hover on the design model: the hover LQR through a Forecaster, the truth a
StatePredictor of its own airframe, for the observer's tests (torque bias, rotor lag)."""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from mavreg.config.vehicle import G
from mavreg.control.estimation.forecast import Forecaster
from mavreg.control.controllers.hover import HoverController, HoverParams, Ramp
from mavreg.control.estimation.predictor import StatePredictor


def fly_hover(fc: Forecaster, truth: StatePredictor, ramp_at: Callable[[float], Ramp], seconds: float,
              rng: np.random.Generator, delay_s: float = 0.012, extra_delay_s: float = 0.0,
              truth_torque: Callable[[np.random.Generator], tuple] | None = None,
              rate_noise_rad_s: float = 0.005, dt_s: float = 0.002) -> np.ndarray:
    """Fly ``seconds`` from a level hover at 10 m (the rotors at the hover's forces) and
    return the true states (n, 12). The controller predicts across ``delay_s``; the truth's
    commands act ``delay_s + extra_delay_s`` after the sample they answer; the rates are
    measured with ``rate_noise_rad_s`` of white noise; ``truth_torque(rng)`` (6,) is the
    truth's torque bias each step (None: none); ``ramp_at(t)`` the hover's reference."""
    vehicle = fc.vehicle
    hover = HoverController(vehicle, HoverParams())
    hover_n = vehicle.mass_kg * G
    fc.reset((hover_n / 4,) * 4)
    truth.reset((hover_n / 4,) * 4)
    fc.observing = True
    x = np.zeros(12)
    x[2] = -10.0
    R = np.eye(3)
    states = np.empty((int(seconds / dt_s), 12))
    for k in range(len(states)):
        t = k * dt_s
        seen = x.copy()
        seen[9:12] += rng.normal(0.0, rate_noise_rad_s, 3)
        f = fc.update(t, seen, R, delay_s)
        cmd = fc.command(t, hover.step(f.x, ramp_at(t), t, fc.disturbance).rotor_forces_n)
        truth.record(t, cmd)
        p = truth.predict(t, x, R, dt_s, delay_s=delay_s + extra_delay_s,
                          torque_bias=None if truth_torque is None else truth_torque(rng))
        x, R = p.x, p.rotation
        states[k] = x
    return states
