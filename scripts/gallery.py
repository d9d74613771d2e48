"""Make docs/gallery.md: every maneuver of params/maneuvers/, planned and flown, with figures.

For each file: plan it (params/controller/design.yaml) and save its plan figure
(``mavreg plan --plot``: docs/gallery/<name>_plan.png); fly it on the design model from
0.6 m off its entry in north, east and down (``mavreg simulate --entry-offset 0.6 0.6 0.6 --plot``:
<name>_simulate.png); with ``--sitl`` fly it through the daemon against firmware_sim in
lockstep in the ideal world with the paper's weights (design.yaml) and in the realistic world
(20 ms rotor lag, link delay, estimate noise, drag) with realistic.yaml, keeping the realistic
flight's flight.png (<name>_fly.png), and fly one failure on purpose (the barrel roll on three
times the design inertia: failed_barrel_roll_fly.png). The table's design-model column is the
flight from the nominal entry. Writes docs/gallery/*.png, results.json and docs/gallery.md
(the captions are in scripts/gallery_text.py).

    python scripts/gallery.py [--sitl] [--only NAME ...] [--markdown-only]

The SITL flights take about half a minute each (15 with --sitl); run them on a quiet
machine (lockstep keeps the results independent of the load, not the time).
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mavreg.config.paths import (DEFAULT_VEHICLE, DESIGN_CONTROLLER, PAPER_CONTROLLER,  # noqa: E402
                                 PARAMS_DIR, REAL_CONTROLLER)
from mavreg.config.controller import load_controller  # noqa: E402
from mavreg.config.maneuver import load_maneuver  # noqa: E402
from mavreg.config.vehicle import load_vehicle  # noqa: E402
from mavreg.maneuver.nominal_table import rotor_forces_n  # noqa: E402
from mavreg.maneuver.plan import plan_spec  # noqa: E402
from mavreg.plots import plot_plan, plot_simulation  # noqa: E402
from mavreg.sim.maneuver_run import fly_on_design_model  # noqa: E402

from gallery_text import markdown  # noqa: E402

LIBRARY = PARAMS_DIR / "maneuvers"
OUT = ROOT / "docs" / "gallery"
ORDER = ("barrel_roll", "forward_loop", "split_s", "immelmann", "figure_eight",
         "climbing_helix", "slalom")
OFFSET_M = (0.6, 0.6, 0.6)
"""The simulate figure's start error (the paper's Section 4): 1.04 m off the entry."""
FAILED = ("barrel_roll", "ideal", PAPER_CONTROLLER, ("--emulator-arg=--inertia-scale=3",))
"""The failure flown on purpose: three times the design inertia in the paper's world."""


def design_flight(plan) -> dict:
    """The table's design-model cell: the flight from the nominal entry."""
    run = fly_on_design_model(plan, true_metrics=False)
    m = run.metrics
    return {"status": m["status"], "transverse_mm": 1e3 * m["transverse_error_m"]["max"],
            "attitude_deg": m["attitude_error_deg"]["max"],
            "peak_rotor_n": float(np.max(run.result.rotor_command_n)),
            "nominal_peak_rotor_n": float(np.max(rotor_forces_n(plan)))}


def offset_figure(plan, png: Path) -> dict:
    """``mavreg simulate --entry-offset 0.6 0.6 0.6 --plot``'s figure; its status and errors."""
    run = fly_on_design_model(plan, offset_m=OFFSET_M, true_metrics=False)
    plot_simulation(png, plan, run, 1000.0, f"{plan.name} on the design model (offset "
                    f"{' '.join(f'{v:g}' for v in OFFSET_M)} m NED, control 1000 Hz)")
    m = run.metrics
    return {"status": m["status"], "transverse_m": m["transverse_error_m"]["max"]}


def sitl_flight(maneuver: Path, world: str, controller: Path, png: Path | None = None,
                extra: tuple[str, ...] = ()) -> dict:
    """One lockstep ``mavreg fly`` on the bundled emulator; its flight.png copied to ``png``."""
    with tempfile.TemporaryDirectory() as out:
        proc = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "fly", str(maneuver),
                               "--lockstep", "--world", world, "--controller", str(controller),
                               "--out", out, *extra], capture_output=True, text=True, timeout=900)
        try:
            summary = json.loads((Path(out) / "summary.json").read_text())
        except (OSError, ValueError):
            return {"ok": False, "reason": " ".join((proc.stderr or proc.stdout).strip().splitlines()[-1:])}
        if png is not None and (Path(out) / "flight.png").exists():
            shutil.copyfile(Path(out) / "flight.png", png)
    truth = summary["ground_truth"] or {}
    return {"ok": proc.returncode == 0, "transverse_cm": 100 * (truth.get("max_m") or float("nan")),
            "attitude_deg": truth.get("max_deg") or float("nan"),
            "controller": summary["controller_metrics"], "reason": summary["reason"]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sitl", action="store_true", help="also fly each through the daemon in lockstep SITL")
    p.add_argument("--only", nargs="+", metavar="NAME", help="these maneuvers only")
    p.add_argument("--markdown-only", action="store_true",
                   help="rewrite docs/gallery.md from docs/gallery/results.json (new captions), fly nothing")
    args = p.parse_args()
    if args.markdown_only:
        res = json.loads((OUT / "results.json").read_text())
        sitl = any("sitl_realistic" in r for r in res["maneuvers"])
        (ROOT / "docs" / "gallery.md").write_text(markdown(res["maneuvers"], sitl, res["failed"]))
        return 0
    OUT.mkdir(parents=True, exist_ok=True)
    vehicle = load_vehicle(DEFAULT_VEHICLE)
    controller = load_controller(DESIGN_CONTROLLER)
    rows = []
    for name in args.only or ORDER:
        path = LIBRARY / f"{name}.yaml"
        spec = load_maneuver(path)
        plan = plan_spec(spec, vehicle, controller)
        plot_plan(OUT / f"{name}_plan.png", plan)
        row = {"name": name, "description": spec.description, "yaw_mode": spec.yaw.mode,
               "length_m": plan.length_m, "duration_s": plan.duration_s,
               "max_pitch_deg": float(np.degrees(np.abs(plan.x[:, 4]).max())),
               "design": design_flight(plan), "offset": offset_figure(plan, OUT / f"{name}_simulate.png")}
        if args.sitl:
            row["sitl_ideal"] = sitl_flight(path, "ideal", DESIGN_CONTROLLER)
            row["sitl_realistic"] = sitl_flight(path, "realistic", REAL_CONTROLLER, OUT / f"{name}_fly.png")
        print(json.dumps(row), flush=True)
        rows.append(row)
    failed = None
    if args.sitl and not args.only:
        name, world, ctl, extra = FAILED
        failed = sitl_flight(LIBRARY / f"{name}.yaml", world, ctl, OUT / f"failed_{name}_fly.png", extra)
        print(json.dumps({"failed": failed}), flush=True)
    if args.only and (OUT / "results.json").exists():     # a re-run replaces its rows, keeps the rest
        old = json.loads((OUT / "results.json").read_text())
        new = {r["name"]: r for r in rows}
        rows = [new.pop(r["name"], r) for r in old["maneuvers"]] + list(new.values())
        failed = old["failed"]
    (OUT / "results.json").write_text(json.dumps({"maneuvers": rows, "failed": failed}, indent=2))
    sitl = any("sitl_realistic" in r for r in rows)
    (ROOT / "docs" / "gallery.md").write_text(markdown(rows, sitl, failed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
