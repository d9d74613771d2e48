"""The daemon's per-sample chain replayed on saved samples (tests/unit/test_controller_replay.py),
in a child process of its own so that the compiled kernels and ``MAVREG_PURE=1`` each get a
fresh interpreter:

    python -m tests.helpers.controller_replay PHASE SAMPLES.npz OUT.npy
"""
from __future__ import annotations

import sys

import numpy as np

from mavreg.control.controllers.hover import HoverController, HoverParams
from harness import controller_flight as flight

OBSERVER_OFF_SAMPLES = 50
GAPS = ((300, 303), (900, 901), (1200, 1230))
"""Samples dropped (index ranges of the replay): 3 and 1 missed periods, a 60 ms stall."""


def chain(phase: str, samples: np.lib.npyio.NpzFile) -> np.ndarray:
    """Every output of the per-sample chain, one row per replayed sample."""
    setup = flight.Setup()
    fc = setup.forecaster()
    fc.observing = False
    fc.reset(np.full(4, setup.vehicle.mass_kg * 9.81 / 4))
    t, x, R, delay = samples["t"], samples["x"], samples["R"], samples["delay"]
    if phase == "hover":
        ctl, ramp = HoverController(setup.vehicle, HoverParams()), flight.hover_ramp(x[0])
    else:
        reg = setup.regulator()
        reg.reset(x[0], s_guess=float(samples["s0"]))
    dropped = {i for a, b in GAPS for i in range(a, b)}
    rows = []
    for i in range(len(t)):
        if i in dropped:
            continue
        fc.observing = i >= OBSERVER_OFF_SAMPLES
        f = fc.update(t[i], x[i], R[i], delay[i])
        out = (ctl.step(f.x, ramp, t[i], fc.disturbance) if phase == "hover"
               else reg.step(f.x, f.rotor_forces_n, fc.disturbance))
        cmd = fc.command(t[i], out.rotor_forces_n)
        if i % 97 == 0:                              # the same sample answered again
            cmd = fc.command(t[i], 0.9 * out.rotor_forces_n)
        ahead = fc.ahead(t[i], x[i], R[i], (1 + i % 60) * 0.002, delay[i])
        est = fc.observer.estimate
        applied = fc.disturbance
        rows.append(np.concatenate([
            f.x, np.ravel(f.rotation), f.rotor_forces_n, [f.horizon_s], out.u, out.rotor_forces_n, cmd,
            est.drag_n_s_per_m, est.force_ned_n, [est.thrust_scale],
            applied.drag_n_s_per_m, applied.force_ned_n, [applied.thrust_scale],
            np.full(16, np.nan) if ahead is None else np.concatenate([ahead.x, ahead.rotor_forces_n])]))
    return np.array(rows)


def chain_outputs(phase: str, samples_path: str, out_path: str) -> None:
    """Child process entry: replay the saved samples, save the outputs."""
    np.save(out_path, chain(phase, np.load(samples_path)))


if __name__ == "__main__":
    chain_outputs(*sys.argv[1:])
