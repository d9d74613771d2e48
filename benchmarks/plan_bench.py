"""Planning the barrel roll (loaded YAML to gain schedule), by stage, and a cached replan.

``run_plan(quick)`` returns figures (:func:`benchmarks.io_helpers.figure`):

- ``plan_s.total`` and its stages ``plan_s.path`` (path, profiles and grid),
  ``plan_s.nominal`` (with feasibility), ``plan_s.linearization``, ``plan_s.riccati``:
  :func:`mavreg.maneuver.plan.plan_spec` of ``barrel_roll.yaml`` with the paper's controller
  (``paper_lqr.yaml``), the stage times it reports through ``timings=``; median of 3 (quick: 1)
  after one untimed plan (numba compiles or loads its kernels there). Baseline: the same
  plan on the pure path (``MAVREG_PURE=1``: no compiled kernel, the Riccati sweep and the
  rest in numpy), in a child process of the same run, one plan after an untimed one;
- ``plan_s.cache_hit``: replanning the unchanged maneuver through a plan cache
  (:func:`mavreg.maneuver.plan.plan_cached` on a fresh directory: one miss, then the timed
  hit), against planning it.

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

from benchmarks.io_helpers import BARREL, PAPER_CONTROLLER, VEHICLE, figure
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver
from mavreg.config.vehicle import load_vehicle
from mavreg.maneuver import plan as planmod

__all__ = ["run_plan", "plan_stages"]

STAGES = ("path", "nominal", "linearization", "riccati")
TARGET_TOTAL_S = 0.15


def plan_stages(spec, vehicle, controller) -> dict:
    """Seconds of one :func:`plan_spec` call: ``total`` and, when ``plan_spec`` reports them
    (its ``timings=`` keyword), the stages of :data:`STAGES`."""
    if "timings" in inspect.signature(planmod.plan_spec).parameters:
        timings: dict = {}
        t0 = time.perf_counter()
        planmod.plan_spec(spec, vehicle, controller, timings=timings)
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
    if not hasattr(planmod, "plan_cached"):
        return None
    from mavreg.maneuver.cache import PlanCache
    with tempfile.TemporaryDirectory(prefix="bench_plan_cache_") as tmp:
        cache = PlanCache(tmp)
        planmod.plan_cached(spec, vehicle, controller, cache=cache)
        t0 = time.perf_counter()
        planmod.plan_cached(spec, vehicle, controller, cache=cache)
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
    return fig


if __name__ == "__main__":
    from benchmarks.report import standalone
    standalone(run_plan, __doc__)
