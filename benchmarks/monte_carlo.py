"""The paper's Monte Carlo on the design model, vectorized across runs, against one run at a time.

``run_monte_carlo(quick)`` returns figures (:func:`benchmarks.io_helpers.figure`):

- ``monte_carlo_s.group1``: wall seconds of :func:`mavreg.sim.batch.fly_batch` flying the
  26 runs of the paper's group 1 (:func:`mavreg.experiments.definitions.paper_group1`,
  seed 0: 0.6 m off in each axis, nominal and 25 drawn inertias; ``paper_lqr.yaml``; the
  whole barrel roll, regulator at 1 kHz, RK4 at 1 ms). The plan is made beforehand, and
  one tiny batch first loads (or compiles, on a fresh checkout) the numba kernels.
  Baseline: the sequential simulator (:func:`mavreg.sim.maneuver_run.fly_on_design_model`,
  what ``mavreg experiment --via sim`` flies), timed on the first run (quick: its first
  2 s) and scaled by the number of physics steps to all 26;
- ``monte_carlo_sim_s_per_wall_s.group1``: simulated seconds (summed over runs) per wall
  second, batch against sequential;
- ``monte_carlo_agreement_m.group1``: the largest difference of any state between the batch
  and the sequential run timed (the tests hold it under 1e-9);
- ``monte_carlo_s.group2`` and ``monte_carlo_s.paper``: group 2 (3 runs of 3 laps, 0.1 N
  rotor noise, saturation none / 8.5 / 7 N, one batch) and both groups (29 runs), planning
  excluded; baseline scaled from the sequential rate above;
- ``experiment_s.paper_group1`` (full run only): ``mavreg experiment paper-group1 --via sim
  --jobs 2`` in a child process, its campaign's own wall time (plan, fly and judge the 26
  runs: ``results.json``'s ``wall_time_s``), against ``monte_carlo_s.group1`` of the same
  run; target 5x it (issue 30). ``experiment_command_s.paper_group1``: the whole command
  (interpreter, imports, the campaign, its five figures);
- ``monte_carlo_s.group1_numpy`` (full run with numba only): group 1 on the batch's numpy
  path, the one taken without numba, timed over the first 5 s of flight and scaled by
  physics steps, against the same baseline.

Run alone: ``python -m benchmarks.monte_carlo [--quick]``.
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.io_helpers import BARREL, PAPER_CONTROLLER, VEHICLE, env_with_io, figure
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.experiments.definitions import paper_group1, paper_group2
from mavreg.planning.plan_io import plan_file
from mavreg.sim.batch import BatchRun, fly_batch
from mavreg.sim.maneuver_run import fly_on_design_model

__all__ = ["run_monte_carlo", "time_batch"]

TARGETS_S = {"group1": 1.0, "paper": 2.0}
CAMPAIGN_TIMES_BATCH = 5.0
"""The campaign's goal: within this many times the batch kernel's time (issue 30)."""
NUMPY_SAMPLE_S = 5.0
"""Seconds of flight over which the numpy path is timed (its cost per step is even)."""


def _batch_runs(experiment) -> list[BatchRun]:
    return [BatchRun(r.offset_m, r.inertia_kg_m2, r.rotor_noise_sd_n, r.saturation_n, r.seed)
            for r in experiment.runs]


def time_batch(plan, runs, compiled: bool | None = None) -> tuple[float, list]:
    """Wall seconds of one :func:`fly_batch` of ``runs`` (after a tiny one that loads the
    compiled kernels), and its results."""
    fly_batch(plan, runs[:1], extra_time_s=0.01 - plan.duration_s, compiled=compiled)
    t0 = time.perf_counter()
    results = fly_batch(plan, runs, compiled=compiled)
    return time.perf_counter() - t0, results


def _sequential(plan, run, batch_result, quick: bool) -> tuple[float, float]:
    """(seconds per physics step, largest state difference from the batch's record) of the
    sequential simulator flying ``run`` (quick: its first 2 s)."""
    t0 = time.perf_counter()
    seq = fly_on_design_model(plan, offset_m=run.offset_m, inertia_kg_m2=run.inertia_kg_m2,
                              rotor_noise_sd_n=run.rotor_noise_sd_n, saturation_n=run.saturation_n, seed=run.seed,
                              extra_time_s=2.0 - plan.duration_s if quick else 5.0).result
    wall = time.perf_counter() - t0
    return wall / (len(seq.t) - 1), float(np.abs(seq.x - batch_result.x[:len(seq.x)]).max())


def _steps(results) -> int:
    return sum(len(r.t) - 1 for r in results)


def _campaign(batch_wall_s: float) -> dict:
    """``mavreg experiment paper-group1 --via sim --jobs 2`` in a child process: the campaign
    (its ``wall_time_s``: planning, flying and judging the 26 runs) and the whole command
    (interpreter, imports, figures and files), each against this run's batch."""
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "mavreg.cli.main", "experiment", "paper-group1", "--via", "sim",
                        "--jobs", "2", "--out", tmp], check=True, capture_output=True, env=env_with_io("fast"))
        command_s = time.perf_counter() - t0
        campaign_s = json.loads((Path(tmp) / "results.json").read_text())["wall_time_s"]
    return {
        "experiment_s.paper_group1": figure(
            campaign_s, batch_wall_s, target=CAMPAIGN_TIMES_BATCH * batch_wall_s, unit="s", higher_is_better=False,
            note=f"mavreg experiment paper-group1 --via sim --jobs 2, its campaign (plan, 26 runs, their truth and "
                 f"metrics: results.json wall_time_s); baseline monte_carlo_s.group1; target "
                 f"{CAMPAIGN_TIMES_BATCH:g}x the baseline (issue 30)"),
        "experiment_command_s.paper_group1": figure(
            command_s, batch_wall_s, unit="s", higher_is_better=False,
            note="the same command as a whole: interpreter, imports, kernels loaded, the campaign, 5 figures, "
                 "results files; baseline monte_carlo_s.group1"),
    }


def run_monte_carlo(quick: bool) -> dict:
    """All the figures of the module docstring."""
    from mavreg import accel
    vehicle = load_vehicle(VEHICLE)
    controller = load_controller(PAPER_CONTROLLER)
    plan = plan_file(BARREL, vehicle, controller)
    runs = _batch_runs(paper_group1(seed=0))
    wall, results = time_batch(plan, runs)
    per_step, diff = _sequential(plan, runs[0], results[0], quick)
    steps = _steps(results)
    sim_s = sum(float(r.t[-1]) for r in results)
    path = "compiled (numba)" if accel.ACCELERATED else f"numpy ({accel.reason})"
    subset = "the first 2 s of run 0" if quick else "run 0"
    note = (f"{len(runs)} runs, {sim_s:.0f} s simulated, {steps} physics steps, batch {path}; baseline: "
            f"fly_on_design_model timed on {subset} ({per_step * 1e6:.0f} us a step) and scaled to all steps")
    fig = {
        "monte_carlo_s.group1": figure(wall, per_step * steps, target=TARGETS_S["group1"], unit="s",
                                       higher_is_better=False, note=note),
        "monte_carlo_sim_s_per_wall_s.group1": figure(sim_s / wall, sim_s / (per_step * steps), unit="sim s/s",
                                                      higher_is_better=True, note=note),
        "monte_carlo_agreement_m.group1": figure(diff, None, target=1e-9, unit="m, rad, m/s", higher_is_better=False,
                                                 note=f"largest state difference, batch against sequential, {subset}"),
    }
    g2 = paper_group2(seed=0)
    plan2 = plan_file(BARREL, vehicle, controller, laps=g2.runs[0].laps)
    wall2, results2 = time_batch(plan2, _batch_runs(g2))
    steps2 = _steps(results2)
    fig["monte_carlo_s.group2"] = figure(
        wall2, per_step * steps2, unit="s", higher_is_better=False,
        note=f"{len(results2)} runs of {g2.runs[0].laps} laps, {steps2} physics steps; baseline scaled as group 1's")
    fig["monte_carlo_s.paper"] = figure(
        wall + wall2, per_step * (steps + steps2), target=TARGETS_S["paper"], unit="s", higher_is_better=False,
        note="groups 1 and 2 (29 runs), planning excluded; baseline scaled as group 1's")
    if not quick:
        fig.update(_campaign(wall))
    if not quick and accel.ACCELERATED:
        t0 = time.perf_counter()
        part = fly_batch(plan, runs, extra_time_s=NUMPY_SAMPLE_S - plan.duration_s, compiled=False)
        numpy_s = (time.perf_counter() - t0) * steps / _steps(part)
        fig["monte_carlo_s.group1_numpy"] = figure(
            numpy_s, per_step * steps, target=TARGETS_S["group1"], unit="s", higher_is_better=False,
            note=f"group 1 on the batch's numpy path (the one without numba), timed over the first "
                 f"{NUMPY_SAMPLE_S:g} s of flight and scaled to all steps")
    return fig


if __name__ == "__main__":
    from benchmarks.report import standalone
    standalone(run_monte_carlo, __doc__, quick_help="sequential baseline from 2 s of one run, no pure-numpy run")
