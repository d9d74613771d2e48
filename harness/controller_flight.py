"""A closed-loop flight of the daemon's per-sample chain on the design model, recorded.

The forecaster (delay prediction, the disturbance observer), the hover LQR or the maneuver
regulator on the forecast, and the command's bookkeeping, built from ``realistic.yaml`` as
the daemon builds them at 500 Hz, flown on the design model with the rotors lagging 20 ms, the
state seen 14 ms late and the command acting 6 ms later, and a steady 0.6 N side force for
the observer to find. :func:`fly` returns the samples the controller was handed, for the
tests that replay them (compiled against pure) and for ``benchmarks.controller_bench``,
which times the replay.
"""
from __future__ import annotations

import numpy as np

from mavreg.config.defaults import CONTROL_RATE_HZ
from mavreg.control.estimation.forecast import Forecaster
from mavreg.control.controllers.hover import HoverController, HoverParams, plan_ramp
from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.closed_loop import SimOptions, simulate
from harness import params

__all__ = ["RATE_HZ", "MEASUREMENT_DELAY_S", "COMMAND_DELAY_S", "SIDE_FORCE_N", "Setup", "hover_ramp", "fly",
           "hover_forecasts"]

RATE_HZ = CONTROL_RATE_HZ
MEASUREMENT_DELAY_S = 0.014
COMMAND_DELAY_S = 0.006
SIDE_FORCE_N = (0.3, 0.5, 0.0)


class Setup:
    """The vehicle, the realistic controller file, the barrel roll's plan, and builders of
    the daemon's objects (fresh for each flight and each replay)."""

    def __init__(self):
        self.vehicle = params.vehicle()
        self.controller = params.controller("realistic")
        self.plan = params.barrel_roll_plan("realistic")

    def forecaster(self) -> Forecaster:
        c = self.controller
        f = Forecaster(self.vehicle, 1.0 / RATE_HZ, predict=c.predict_delay, max_horizon_s=c.max_prediction_s,
                       disturbance=c.disturbance)
        f.observing = True
        return f

    def regulator(self) -> ManeuverRegulator:
        c = self.controller
        return ManeuverRegulator(self.plan, self.vehicle, control_period_s=1.0 / RATE_HZ,
                                 max_compensation_turn_rad=c.disturbance.max_compensation_turn_rad,
                                 allocation=c.allocation, speed_governor=c.speed_governor)


def hover_ramp(x0):
    """The take-off ramp of the hover flight: from ``x0``'s position to 0.5 m north, 0.3 m west,
    1.5 m up."""
    p0 = np.asarray(x0[:3], dtype=float)
    return plan_ramp(p0, np.zeros(3), 0.0, p0 + np.array([0.5, -0.3, -1.5]), np.zeros(3), 0.0, HoverParams())


def fly(setup: Setup, phase: str, duration_s: float) -> list:
    """One closed-loop flight of ``phase`` ("hover" or "maneuver"): the samples
    ``(t_s, x, R, delay_s)`` the controller was handed, in order."""
    v = setup.vehicle
    horizon = MEASUREMENT_DELAY_S + COMMAND_DELAY_S
    fc = setup.forecaster()
    samples = []
    if phase == "hover":
        x0 = np.zeros(12)
        ctl, ramp = HoverController(v, HoverParams()), hover_ramp(x0)
    else:
        x0 = setup.plan.entry_state.copy()
        reg = setup.regulator()
        reg.reset(x0, s_guess=0.0)
    fc.reset(np.full(4, v.mass_kg * 9.81 / 4))

    def controller(t, x):
        t_s = t - MEASUREMENT_DELAY_S
        R = rpy_to_matrix(*x[3:6])
        samples.append((t_s, x.copy(), R, horizon))
        f = fc.update(t_s, x, R, horizon)
        if phase == "hover":
            out = ctl.step(f.x, ramp, t_s, fc.disturbance)
        else:
            out = reg.step(f.x, f.rotor_forces_n, fc.disturbance)
        return fc.command(t_s, out.rotor_forces_n)

    opts = SimOptions(initial_state=tuple(x0), dt_s=1e-3, control_period_steps=2,
                      max_duration_s=duration_s, rotor_time_constant_s=v.rotor_time_constant_s,
                      measurement_delay_s=MEASUREMENT_DELAY_S, command_delay_s=COMMAND_DELAY_S,
                      force_fn=lambda t, x: np.asarray(SIDE_FORCE_N), attitude="so3",
                      done=None if phase == "hover" else (lambda t, x: reg.s >= setup.plan.length_m - 1e-6))
    res = simulate(QuadrotorModel.from_vehicle(v), Mixer.from_vehicle(v), controller, opts)
    if res.status.value == "diverged":
        raise RuntimeError(f"the {phase} flight diverged: {res.reason}")
    return samples


def hover_forecasts() -> np.ndarray:
    """The forecaster's outputs (x, R, rotor forces, and the observer's estimate after each
    sample) over a 3 s hover flight, each command answered as the flight answered it (a child
    process's work in ``test_controller_bench.py``: compiled against ``MAVREG_PURE=1``)."""
    setup = Setup()
    samples = fly(setup, "hover", 3.0)
    hover = HoverController(setup.vehicle, HoverParams())
    ramp = hover_ramp(samples[0][1])
    fc = setup.forecaster()
    fc.reset(np.full(4, setup.vehicle.mass_kg * 9.81 / 4))
    rows = []
    for t, x, R, delay in samples:
        f = fc.update(t, x, R, delay)
        fc.command(t, hover.step(f.x, ramp, t, fc.disturbance).rotor_forces_n)
        rows.append(np.concatenate([f.x, f.rotation.ravel(), f.rotor_forces_n, fc.observer.theta, fc.observer.P[0]]))
    return np.array(rows)
