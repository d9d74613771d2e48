"""Planning the barrel roll (loaded YAML to gain schedule), by stage, and a cached replan.

``run_plan(quick)`` returns figures (:func:`benchmarks.io_helpers.figure`):

- ``plan_s.total`` and its stages ``plan_s.path`` (path, profiles and grid),
  ``plan_s.nominal`` (with feasibility), ``plan_s.linearization``, ``plan_s.riccati``:
  :func:`mavreg.maneuver.plan.plan_spec` of ``barrel_roll.yaml`` with the paper's controller
  (``paper_lqr.yaml``), the stage times it reports through ``timings=`` (on the clock it is handed); median of 3 (quick: 1)
  after one untimed plan (numba compiles or loads its kernels there). Baseline: the same
  plan on the pure path (``MAVREG_PURE=1``: no compiled kernel, the Riccati sweep and the
  rest in numpy), in a child process of the same run, one plan after an untimed one;
- ``plan_s.cache_hit``: replanning the unchanged maneuver through a plan cache
  (:func:`mavreg.planning.plan_io.plan_cached` on a fresh directory: one miss, then the timed
  hit), against planning it;
- ``plan_rss_mb.peak``: the peak resident memory of ``mavreg plan barrel_roll.yaml`` (the
  design controller, no plan cache, margins included), a child process's own high-water mark
  (``VmHWM``); ``plan_rss_mb.floor`` the same child's right after it imported the planner
  and loaded numba's compiled kernels, before any table of the plan existed (what a plan can
  not go below in a process that uses the kernels);
- ``plan_cache_entry_mb``: the size of the barrel roll's plan-cache entry (design
  controller), against the pickle of the whole plan (what an entry held before);
- ``rejected_file_s``: ``mavreg plan /dev/null`` (an empty file, refused), a child process
  from start to exit, against importing the planner alone (what the command cost when it
  imported the planner first).

Run alone: ``python -m benchmarks.plan_bench [--quick]``.
"""
from __future__ import annotations

import inspect
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

from pathlib import Path

from benchmarks.io_helpers import BARREL, PAPER_CONTROLLER, REPO, VEHICLE, figure
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.vehicle import load_vehicle
from mavreg.maneuver import plan as planmod

__all__ = ["run_plan", "plan_stages"]

STAGES = ("path", "nominal", "linearization", "riccati")
TARGET_TOTAL_S = 0.15
TARGET_RSS_MB = 150.0
TARGET_ENTRY_MB = 2.0
TARGET_REJECTED_S = 1.0

_RSS_PROBE = """
import sys
def hwm():
    status = dict(line.split(':', 1) for line in open('/proc/self/status'))
    return int(status['VmHWM'].split()[0]) / 1024
from mavreg.cli.main import main
import mavreg.maneuver.plan, mavreg.maneuver.plan_margins, mavreg.control.design.riccati as r
import numpy as np
r.sweep_backward(np.zeros((2, 11, 11)), np.ones((2, 11, 4)), np.zeros((1, 11, 11)),
                 np.ones((1, 11, 4)), 0.01, np.eye(11), np.eye(4), np.eye(11), step_check='off')
floor = hwm()
code = main(['plan', sys.argv[1], '--controller', sys.argv[2]])
print('RSS', floor, hwm(), code)
"""


def plan_stages(spec, vehicle, controller) -> dict:
    """Seconds of one :func:`plan_spec` call: ``total`` and, when ``plan_spec`` reports them
    (its ``timings=`` keyword), the stages of :data:`STAGES`."""
    params = inspect.signature(planmod.plan_spec).parameters
    if "timings" in params:
        timings: dict = {}
        clock = {"clock": time.perf_counter} if "clock" in params else {}    # the planner reads none
        t0 = time.perf_counter()
        planmod.plan_spec(spec, vehicle, controller, timings=timings, **clock)
        timings.setdefault("total", time.perf_counter() - t0)
        return timings
    t0 = time.perf_counter()
    planmod.plan_spec(spec, vehicle, controller)
    return {"total": time.perf_counter() - t0}


def _median_stages(spec, vehicle, controller, repeats: int) -> dict:
    planmod.plan_spec(spec, vehicle, controller)          # warm-up: compiled kernels, imports
    runs = [plan_stages(spec, vehicle, controller) for _ in range(repeats)]
    return {k: statistics.median(r[k] for r in runs) for k in runs[0] if all(k in r for r in runs)}


def _cache_hit_s(spec, vehicle, controller) -> float | None:
    from mavreg.planning.cache import PlanCache
    from mavreg.planning.plan_io import plan_cached
    with tempfile.TemporaryDirectory(prefix="bench_plan_cache_") as tmp:
        cache = PlanCache(tmp)
        plan_cached(spec, vehicle, controller, cache=cache)
        t0 = time.perf_counter()
        plan_cached(spec, vehicle, controller, cache=cache)
        hit = time.perf_counter() - t0
        if cache.hits != 1:
            raise RuntimeError(f"the plan cache did not hit ({cache.hits} hits, {cache.misses} misses)")
    return hit


def _pure_stages() -> dict:
    """The stages of one plan on the pure path (``MAVREG_PURE=1``), in a child process (the
    switch is read at import)."""
    code = ("import json; from benchmarks import plan_bench as b; "
            "print(json.dumps(b._stages_of_default_plan(1)))")
    env = dict(os.environ, MAVREG_PURE="1")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    if out.returncode != 0:
        raise RuntimeError(f"the pure-path plan failed: {out.stderr.strip()[-500:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _stages_of_default_plan(repeats: int) -> dict:
    """Median stages of planning the barrel roll with the paper's controller."""
    return _median_stages(load_maneuver(BARREL), load_vehicle(VEHICLE), load_controller(PAPER_CONTROLLER),
                          repeats)


def _child_s(args: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *args], env=env, capture_output=True, timeout=300, cwd=REPO)
    return time.perf_counter() - t0


def weight_figures(quick: bool) -> dict:
    """``plan_rss_mb.*``, ``plan_cache_entry_mb`` and ``rejected_file_s`` (module docstring)."""
    import pickle

    from mavreg.cli.common import DESIGN_CONTROLLER
    from mavreg.planning.cache import PlanCache
    from mavreg.planning.plan_io import plan_cached
    env = dict(os.environ, MAVREG_PLAN_CACHE="off")
    out = subprocess.run([sys.executable, "-c", _RSS_PROBE, str(BARREL), str(DESIGN_CONTROLLER)], env=env,
                         capture_output=True, text=True, timeout=600, cwd=REPO)
    line = next((ln for ln in out.stdout.splitlines() if ln.startswith("RSS ")), None)
    if line is None:
        raise RuntimeError(f"the memory probe failed: {out.stderr.strip()[-500:]}")
    floor, peak, _ = (float(v) for v in line.split()[1:])
    fig = {"plan_rss_mb.peak": figure(peak, None, target=TARGET_RSS_MB, unit="MB", higher_is_better=False,
                                      note="peak resident memory of `mavreg plan barrel_roll.yaml` (design "
                                           "controller, no cache, with margins), a child's VmHWM"),
           "plan_rss_mb.floor": figure(floor, None, unit="MB", higher_is_better=False,
                                       note="the same child after importing the planner and loading the "
                                            "compiled kernels (numpy, scipy.linalg, numba and LLVM)")}
    vehicle, controller = load_vehicle(VEHICLE), load_controller(DESIGN_CONTROLLER)
    spec = load_maneuver(BARREL)
    with tempfile.TemporaryDirectory(prefix="bench_plan_entry_") as tmp:
        plan = plan_cached(spec, vehicle, controller, cache=PlanCache(tmp))
        entry = sum(f.stat().st_size for f in Path(tmp).iterdir()) / 1e6
    whole = len(pickle.dumps(plan, protocol=pickle.HIGHEST_PROTOCOL)) / 1e6
    fig["plan_cache_entry_mb"] = figure(entry, whole, target=TARGET_ENTRY_MB, unit="MB", higher_is_better=False,
                                        note="the barrel roll's plan-cache entry (design controller); "
                                             "baseline: the pickle of the whole plan")
    runs = 1 if quick else 3
    rejected = statistics.median(_child_s(["-m", "mavreg.cli.main", "plan", "/dev/null"], env)
                                 for _ in range(runs))
    importing = statistics.median(_child_s(["-c", "import mavreg.maneuver.plan"], env) for _ in range(runs))
    fig["rejected_file_s"] = figure(rejected, importing, target=TARGET_REJECTED_S, unit="s",
                                    higher_is_better=False,
                                    note=f"`mavreg plan /dev/null`, a whole process, median of {runs}; "
                                         "baseline: a process that imports the planner")
    return fig


def run_plan(quick: bool) -> dict:
    """All the figures of the module docstring."""
    vehicle = load_vehicle(VEHICLE)
    controller = load_controller(PAPER_CONTROLLER)
    spec = load_maneuver(BARREL)
    repeats = 1 if quick else 3
    now = _median_stages(spec, vehicle, controller, repeats)
    base = _pure_stages()
    what = "baseline: the pure path (MAVREG_PURE=1, no compiled kernel), one plan in a child process"
    note = f"plan_spec(barrel_roll.yaml, mk_quadro, paper_lqr.yaml), median of {repeats}; {what}"
    fig = {"plan_s.total": figure(now["total"], base.get("total"), target=TARGET_TOTAL_S, unit="s",
                                  higher_is_better=False, note=note)}
    for stage in STAGES:
        if stage in now:
            fig[f"plan_s.{stage}"] = figure(now[stage], base.get(stage), unit="s", higher_is_better=False,
                                            note=f"stage of plan_spec ({what})")
    hit = _cache_hit_s(spec, vehicle, controller)
    if hit is not None:
        fig["plan_s.cache_hit"] = figure(hit, now["total"], unit="s", higher_is_better=False,
                                         note="plan_cached of the unchanged maneuver from a warm cache; "
                                              "baseline: planning it (plan_s.total)")
    fig.update(weight_figures(quick))
    return fig


if __name__ == "__main__":
    from benchmarks.report import standalone
    standalone(run_plan, __doc__)
