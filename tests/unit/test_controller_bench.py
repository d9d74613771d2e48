"""``benchmarks.controller_bench``: the daemon's per-sample figures, each with its pure-path baseline.

Asserts no timing: that every part is measured on both paths, and that the flights the
replays time are the closed loops they claim (the hover holds its point, the barrel roll
is flown to its end).
"""
from __future__ import annotations

import sys

import numpy as np

from benchmarks import controller_bench as cb
from harness import controller_flight as flight
from tests.helpers.repo import ROOT as REPO


def test_every_part_has_a_value_and_a_pure_baseline():
    figs = cb.run_controller(quick=True)
    for part in cb.PARTS:
        for q in ("p50", "p99"):
            f = figs[f"controller_us.{part}_{q}"]
            assert f["value"] > 0 and f["baseline"] > 0 and f["ratio"] > 0, (part, q)


def test_the_timed_flights_hold_the_hover_point_and_finish_the_maneuver():
    setup = flight.Setup()
    hover = flight.fly(setup, "hover", 8.0)
    p_end = hover[-1][1][:3]
    assert np.linalg.norm(p_end - np.array([0.5, -0.3, -1.5])) < 0.05
    maneuver = flight.fly(setup, "maneuver", setup.plan.duration_s + 0.5)
    assert len(maneuver) < (setup.plan.duration_s + 0.5) * flight.RATE_HZ     # stopped at the path's end


def test_the_forecaster_compiled_and_pure_agree_over_a_recorded_flight(tmp_path):
    """The same closed-loop hover (observer on, commands recorded) replayed in a process on
    the compiled path and in one on the pure path (MAVREG_PURE=1): the forecasts and the
    observer's state agree to 1e-12 relative after 1500 samples."""
    import os
    import subprocess
    code = ("import sys, numpy as np; from harness.controller_flight import hover_forecasts; "
            "np.save(sys.argv[1], hover_forecasts())")
    out = {}
    for pure in ("0", "1"):
        path = tmp_path / f"f{pure}.npy"
        subprocess.run([sys.executable, "-c", code, str(path)], check=True, timeout=300, cwd=REPO,
                       env=dict(os.environ, MAVREG_PURE=pure))
        out[pure] = np.load(path)
    assert out["0"].shape[0] == 1500 and np.all(np.isfinite(out["0"]))
    scale = np.abs(out["1"]).max(axis=0) + 1e-9
    assert (np.abs(out["0"] - out["1"]) / scale).max() <= 1e-12
