"""``benchmarks.controller_bench``: the daemon's per-sample figures, each with its pure-path baseline.

Asserts no timing: that every part is measured on both paths, and that the flights the
replays time are the closed loops they claim (the hover holds its point, the barrel roll
is flown to its end).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))
from benchmarks import controller_bench as cb  # noqa: E402


def test_every_part_has_a_value_and_a_pure_baseline():
    figs = cb.run_controller(quick=True)
    for part in cb.PARTS:
        for q in ("p50", "p99"):
            f = figs[f"controller_us.{part}_{q}"]
            assert f["value"] > 0 and f["baseline"] > 0 and f["ratio"] > 0, (part, q)


def test_the_timed_flights_hold_the_hover_point_and_finish_the_maneuver():
    setup = cb.Setup()
    hover = cb.fly(setup, "hover", 8.0)
    p_end = hover[-1][1][:3]
    assert np.linalg.norm(p_end - np.array([0.5, -0.3, -1.5])) < 0.05
    maneuver = cb.fly(setup, "maneuver", setup.plan.duration_s + 0.5)
    assert len(maneuver) < (setup.plan.duration_s + 0.5) * cb.RATE_HZ     # stopped at the path's end
