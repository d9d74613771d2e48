"""The daemon's per-sample controller work: forecaster, hover LQR, regulator, command.

``run_controller(quick)`` returns figures (:func:`benchmarks.io_helpers.figure`), microseconds
per sample, p50 and p99:

- ``controller_us.forecast_*``: :meth:`mavreg.control.estimation.forecast.Forecaster.update` with the
  disturbance observer (its own prediction of the sample from the previous one and its
  Kalman update), then the prediction across the link delay;
- ``controller_us.hover_*``: :meth:`mavreg.control.controllers.hover.HoverController.step` on the
  forecast state, the estimate fed forward (take-off ramp, then hold);
- ``controller_us.regulator_*``: :meth:`mavreg.control.controllers.regulator.ManeuverRegulator.step` on
  the forecast state and rotor forces, with the estimate (the barrel roll);
- ``controller_us.command_*``: :meth:`Forecaster.command` (the command's bookkeeping).

The samples are those of two closed-loop flights on the design model with the realistic
controller (``realistic.yaml``: prediction, the observer, the lag-aware SO(3) regulator), as
the daemon runs it at 500 Hz: a hover (take-off ramp to 1.5 m, then hold) and the barrel
roll, the rotors lagging by 20 ms, the state seen 14 ms late and the command acting 6 ms
later, a steady 0.6 N side force for the observer to find (the flights:
``harness/controller_flight.py``, which the tests replay too). Each flight is flown once (its
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

from benchmarks.io_helpers import REPO, figure
from mavreg.config.vehicle import G
from mavreg.control.controllers.hover import HoverController, HoverParams
from harness.controller_flight import Setup, fly, hover_ramp

__all__ = ["run_controller", "replay"]

PARTS = ("forecast", "hover", "regulator", "command")


def replay(setup: Setup, phase: str, samples: list) -> dict:
    """Seconds per sample of each part of the per-sample work (arrays keyed by
    :data:`PARTS`; the controller not flown has no key), over ``samples`` in order."""
    clock = time.perf_counter
    fc = setup.forecaster()
    fc.reset(np.full(4, setup.vehicle.mass_kg * G / 4))
    if phase == "hover":
        ctl, ramp = HoverController(setup.vehicle, HoverParams()), hover_ramp(samples[0][1])
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
