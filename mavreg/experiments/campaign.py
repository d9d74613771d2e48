"""One campaign from start to end: fly the runs, draw the figures, write the results."""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path

from .definitions import CONVERGENCE, DISTURBANCE, Experiment
from .figures import group1_figures, group2_figures
from .figures_disturbance import disturbance_figures
from .report import results_dict, write_results
from .robustness import ROBUSTNESS
from .robustness_figures import robustness_figures
from .runner import RunOutcome, plan_for, run_experiment

__all__ = ["Campaign", "run_campaign"]


@dataclass(frozen=True)
class Campaign:
    """What a campaign produced."""

    results: dict
    """The content of ``results.json``."""
    outcomes: list[RunOutcome]
    files: list[Path]
    """results.json, results.md and the figures."""

    @property
    def all_ok(self) -> bool:
        """Every run met the experiment's criterion."""
        return bool(self.outcomes) and all(o.ok for o in self.outcomes)


def run_campaign(exp: Experiment, via: str, jobs: int, out_dir: Path, command: str,
                 progress=sys.stderr, keep_flight_files: bool = False,
                 dask_address: str | None = None, argv: list[str] | None = None) -> Campaign:
    """Fly ``exp`` (:func:`.runner.run_experiment`, locally or on the Dask cluster at
    ``dask_address``) and write its figures, ``results.json`` and ``results.md`` into
    ``out_dir``. Tracebacks of runs that raised go to ``errors.log``. ``command`` is the
    command that repeats the campaign, ``argv`` the one typed (default: ``command``), for
    the provenance (:mod:`mavreg.provenance`)."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    outcomes = run_experiment(exp, via, jobs, out_dir, progress, keep_flight_files, dask_address)
    wall = time.monotonic() - t0
    failed = [o for o in outcomes if o.traceback]
    if failed:
        (out_dir / "errors.log").write_text("\n".join(f"run {o.spec.index} ({o.spec.label}):\n{o.traceback}"
                                                      for o in failed))
    laps = exp.runs[0].laps
    plan = None if exp.kind == ROBUSTNESS else plan_for(Path(exp.maneuver_path), Path(exp.vehicle_path),
                                                        Path(exp.controller_path), laps)
    if exp.kind == ROBUSTNESS:
        figures = robustness_figures(out_dir, outcomes, exp.cells)
    elif exp.kind == DISTURBANCE:
        figures = disturbance_figures(out_dir, plan, exp.name, outcomes, via)
    elif exp.kind == CONVERGENCE:
        figures = group1_figures(out_dir, plan, outcomes, via, plan.vehicle.inertia_kg_m2)
    else:
        figures = group2_figures(out_dir, plan, outcomes, via)
    extra = {}
    if exp.kind == ROBUSTNESS:
        extra = {"cells": [{"name": c.name, "group": c.group, "title": c.title, "emulator_args": list(c.emulator_args),
                            "maneuver": str(c.maneuver_path), "saturation_n": c.saturation_n,
                            "gust_place": c.gust_place, "mismatch": c.mismatch} for c in exp.cells]}
        if via == "sim":
            from .robustness_sim import sim_description
            extra["sim"] = sim_description()
        else:
            extra["sitl"] = {"world": exp.world, "lockstep": True, "controller_file": str(exp.controller_path),
                             "envelope_changes": None}
    elif via == "sitl":
        from .via_sitl import EXPERIMENT_ENVELOPE
        extra = {"sitl": {"world": "ideal", "lockstep": True, "controller_file": "controller_experiment.yaml",
                          "envelope_changes": EXPERIMENT_ENVELOPE}}
    if dask_address is not None:
        extra["dask"] = dask_address
    extra["provenance"] = _provenance(exp, via, command, argv)
    res = results_dict(exp, via, outcomes, command, min(jobs, len(exp.runs)), wall, figures, extra)
    files = [*write_results(out_dir, res), *figures]
    return Campaign(res, outcomes, files)


def _provenance(exp: Experiment, via: str, command: str, argv: list[str] | None) -> dict:
    """The command, the experiment's files with their hashes, the software (one builder for
    every result file: :func:`mavreg.provenance.provenance`)."""
    import shlex

    from ..provenance import provenance
    files = {"maneuver": exp.maneuver_path, "vehicle": exp.vehicle_path, "controller": exp.controller_path}
    for cell in getattr(exp, "cells", ()):                  # robustness: each cell's maneuver
        files[f"maneuver.{cell.name}"] = cell.maneuver_path
    world = ("the design model (no firmware_sim)" if via == "sim"
             else f"firmware_sim --world {getattr(exp, 'world', None) or 'ideal'}, lockstep")
    return provenance(argv if argv is not None else shlex.split(command), files, world)
