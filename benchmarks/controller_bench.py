"""The daemon's per-sample controller work: forecaster, hover LQR, regulator, command.

``run_controller(quick)`` returns figures (:func:`benchmarks.io_helpers.figure`), microseconds
per sample, p50 and p99:

- ``controller_us.forecast_*``: :meth:`mavreg.control.forecast.Forecaster.update` with the
  disturbance observer (its own prediction of the sample from the previous one and its
  Kalman update), then the prediction across the link delay;
- ``controller_us.hover_*``: :meth:`mavreg.control.hover.HoverController.step` on the
  forecast state, the estimate fed forward (take-off ramp, then hold);
- ``controller_us.regulator_*``: :meth:`mavreg.control.regulator.ManeuverRegulator.step` on
  the forecast state and rotor forces, with the estimate (the barrel roll);
- ``controller_us.command_*``: :meth:`Forecaster.command` (the command's bookkeeping).

The samples are those of two closed-loop flights on the design model with the realistic
controller (``realistic.yaml``: prediction, the observer, the lag-aware SO(3) regulator), as
the daemon runs it at 500 Hz: a hover (take-off ramp to 1.5 m, then hold) and the barrel
roll, the rotors lagging by 20 ms, the state seen 14 ms late and the command acting 6 ms
later, a steady 0.6 N side force for the observer to find. Each flight is flown once (its
samples and commands recorded), then replayed through fresh objects in a timed loop, one
sample after the other (the replay computes what the flight did). Baseline: the same, same
run, in a child process on the pure path (``MAVREG_PURE=1``: the predictor's kernel as plain
Python, the observer's, hover's and regulator's numpy steps).

Run alone: ``python -m benchmarks.controller_bench [--quick]``.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import numpy as np

from benchmarks.io_helpers import BARREL, REALISTIC_CONTROLLER, REPO, VEHICLE, figure
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import G, load_vehicle
from mavreg.control.forecast import Forecaster
from mavreg.control.hover import HoverController, HoverParams, plan_ramp
from mavreg.control.regulator import ManeuverRegulator
from mavreg.maneuver.plan import plan_file
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.closed_loop import SimOptions, simulate

__all__ = ["run_controller", "Setup", "fly", "replay"]

RATE_HZ = 500.0
MEASUREMENT_DELAY_S = 0.014
COMMAND_DELAY_S = 0.006
SIDE_FORCE_N = (0.3, 0.5, 0.0)
PARTS = ("forecast", "hover", "regulator", "command")


class Setup:
    """The vehicle, the realistic controller file, the barrel roll's plan, and builders of
    the daemon's objects (fresh for each flight and each replay)."""

    def __init__(self):
        self.vehicle = load_vehicle(VEHICLE)
        self.controller = load_controller(REALISTIC_CONTROLLER)
        self.plan = plan_file(BARREL, self.vehicle, self.controller)

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


def _hover_ramp(x0):
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
        ctl, ramp = HoverController(v, HoverParams()), _hover_ramp(x0)
    else:
        x0 = setup.plan.entry_state.copy()
        reg = setup.regulator()
        reg.reset(x0, s_guess=0.0)
    fc.reset(np.full(4, v.mass_kg * G / 4))

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


def replay(setup: Setup, phase: str, samples: list) -> dict:
    """Seconds per sample of each part of the per-sample work (arrays keyed by
    :data:`PARTS`; the controller not flown has no key), over ``samples`` in order."""
    clock = time.perf_counter
    fc = setup.forecaster()
    fc.reset(np.full(4, setup.vehicle.mass_kg * G / 4))
    if phase == "hover":
        ctl, ramp = HoverController(setup.vehicle, HoverParams()), _hover_ramp(samples[0][1])
        ctl.gain(0.0)
        step = lambda f, t: ctl.step(f.x, ramp, t, fc.disturbance)       # noqa: E731
    else:
        reg = setup.regulator()
        reg.reset(samples[0][1], s_guess=0.0)
        step = lambda f, t: reg.step(f.x, f.rotor_forces_n, fc.disturbance)   # noqa: E731
    out = np.empty((len(samples), 3))
    for i, (t_s, x, R, delay) in enumerate(samples):
        t0 = clock()
        f = fc.update(t_s, x, R, delay)
        t1 = clock()
        o = step(f, t_s)
        t2 = clock()
        fc.command(t_s, o.rotor_forces_n)
        out[i] = (t1 - t0, clock() - t2, t2 - t1)
    return {"forecast": out[:, 0], "command": out[:, 1], phase if phase == "hover" else "regulator": out[:, 2]}


def measure(quick: bool) -> dict:
    """p50 and p99 (us) of each part, over both flights (the forecast and command parts over
    both, hover and regulator over their own)."""
    setup = Setup()
    hover_s, maneuver_s = (1.5, 1.5) if quick else (8.0, setup.plan.duration_s + 0.5)
    parts: dict = {k: [] for k in PARTS}
    for phase, dur in (("hover", hover_s), ("maneuver", maneuver_s)):
        samples = fly(setup, phase, dur)
        replay(setup, phase, samples[: len(samples) // 4])          # warm-up (compiles, caches)
        for k, v in replay(setup, phase, samples).items():
            parts[k].append(v)
    return {f"{k}_{name}": float(np.percentile(np.concatenate(v), q)) * 1e6
            for k, v in parts.items() for name, q in (("p50", 50.0), ("p99", 99.0))}


def _pure(quick: bool) -> dict:
    """:func:`measure` on the pure path, in a child process (the switch is read at import)."""
    env = dict(os.environ, MAVREG_PURE="1")
    code = "import json, sys; from benchmarks import controller_bench as b; print(json.dumps(b.measure(sys.argv[1] == '1')))"
    out = subprocess.run([sys.executable, "-c", code, "1" if quick else "0"], env=env, capture_output=True,
                         text=True, timeout=900, cwd=REPO)
    if out.returncode != 0:
        raise RuntimeError(f"the pure-path controller benchmark failed: {out.stderr.strip()[-500:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_controller(quick: bool) -> dict:
    """All the figures of the module docstring."""
    now = measure(quick)
    base = _pure(quick)
    note = ("per sample, replaying closed-loop realistic.yaml flights (hover 8 s, barrel roll) on the design model; "
            "baseline: the pure path (MAVREG_PURE=1) in a child process")
    return {f"controller_us.{k}": figure(now[k], base.get(k), unit="us", higher_is_better=False,
                                        note=note if i == 0 else "")
            for i, k in enumerate(now)}


if __name__ == "__main__":
    from benchmarks.report import standalone
    standalone(run_controller, __doc__)
