"""A ``--via sim`` campaign flies its runs in compiled batches (:mod:`mavreg.experiments.via_batch`):
the same numbers as flying them one at a time on the sequential simulator.

A short maneuver with a loop, so that both routes fly every run to its end in seconds: start
offsets, drawn inertias, rotor noise with a saturation; the paper's regulator and the
governed one (torques-first allocation told the run's rotor limit, the speed governor).
"""
from __future__ import annotations

import math
from dataclasses import replace

import pytest

from mavreg import accel
from mavreg.config.paths import PAPER_CONTROLLER, PAPER_GOVERNED_CONTROLLER
from mavreg.experiments import via_batch
from mavreg.experiments.definitions import CONVERGENCE, SATURATION, Experiment, RunSpec
from mavreg.experiments.runner import run_experiment

pytestmark = pytest.mark.skipif(not accel.ACCELERATED, reason="numba is not in use: no batch to compare")

LOOP = """\
kind: maneuver
version: 1
name: little-loop
start: {position_m: [0, 0, -3], heading_deg: 0}
segments:
  - name: run-up
    line: {length_m: 3.0}
  - name: loop
    arc: {radius_m: 2.0, angle_deg: 180, bend_deg: 90}
    blend_m: 1.0
  - name: run-out
    line: {length_m: 2.0}
    blend_m: 1.0
speed: {initial_m_s: 3.0}
laps: {segment: loop, count: 1}
"""


def _close(a, b, path=""):
    """Every number of ``a`` and ``b`` equal to 1e-7 (relative or absolute), the rest equal."""
    if isinstance(a, dict):
        assert a.keys() == b.keys(), path
        for k in a:
            _close(a[k], b[k], f"{path}/{k}")
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and not isinstance(b, bool):
        assert math.isclose(a, b, rel_tol=1e-7, abs_tol=1e-7), (path, a, b)
    else:
        assert a == b, (path, a, b)


@pytest.mark.parametrize("controller,kind", [(PAPER_CONTROLLER, CONVERGENCE), (PAPER_GOVERNED_CONTROLLER, SATURATION)],
                         ids=["paper", "governed"])
def test_batched_runs_give_the_numbers_of_runs_flown_one_at_a_time(tmp_path, monkeypatch, controller, kind):
    maneuver = tmp_path / "little_loop.yaml"
    maneuver.write_text(LOOP)
    runs = (RunSpec(0, "off", (0.3, -0.2, 0.2), seed=1),
            RunSpec(1, "inertia", (0.0, 0.2, 0.0), (0.021, 0.019, 0.04), seed=2),
            RunSpec(2, "noisy, 7 N", rotor_noise_sd_n=0.1, saturation_n=7.0, seed=3),
            RunSpec(3, "noisy", rotor_noise_sd_n=0.1, seed=3))
    exp = Experiment("little", "a short loop", kind, 0, runs, maneuver_path=maneuver, controller_path=controller)
    flown = []
    real = via_batch.fly_batches
    monkeypatch.setattr(via_batch, "fly_batches", lambda *a: flown.extend(a[0]) or real(*a))
    batched = run_experiment(exp, "sim", 1, progress=None)
    assert sorted(s.index for s in flown) == [0, 1, 2, 3]           # every run went through the batch
    monkeypatch.setattr(via_batch, "batchable", lambda *a: False)
    alone = run_experiment(exp, "sim", 1, progress=None)
    assert all(o.metrics is not None and o.metrics["completed"] for o in batched + alone)
    for b, a in zip(batched, alone):
        _close(b.metrics, a.metrics)
    # negative control: another run's numbers are not these
    with pytest.raises(AssertionError):
        _close(batched[0].metrics, replace(alone[1], metrics={**alone[1].metrics, "index": 0}).metrics)


def test_a_run_the_batch_refuses_is_flown_alone_and_fails_alone(tmp_path):
    """A negative inertia stops the batch before it flies: its runs are flown one by one, the
    bad run recorded with its error, the others flown."""
    maneuver = tmp_path / "little_loop.yaml"
    maneuver.write_text(LOOP)
    runs = (RunSpec(0, "fine", (0.1, 0.0, 0.0)), RunSpec(1, "bad", inertia_kg_m2=(-1.0, 0.02, 0.03)))
    outs = run_experiment(Experiment("little", "", CONVERGENCE, 0, runs, maneuver_path=maneuver), "sim", 1,
                          progress=None)
    assert outs[0].metrics is not None and outs[0].metrics["completed"]
    assert outs[1].metrics is None and outs[1].error.startswith("ValueError: inertia_kg_m2 must be 3 positive")
