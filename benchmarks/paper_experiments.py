"""The paper's Section 4 on the design model: Monte Carlo on inertia, noise and saturation.

Run: ``python benchmarks/paper_experiments.py [--runs 25] [--seed 0]``. Prints a table.

Group 1: start 0.6 m off in each axis; one nominal run plus ``--runs`` runs whose plant
inertia jx, jy, jz are drawn around the nominal with SD 0.0102/3 kg m^2 (the controller is
always designed on the nominal). Group 2: nominal start, 0.1 N Gaussian noise on each
rotor force, saturation none / 8.5 N / 7 N, over ``--laps`` laps.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from mavreg.config.paths import PARAMS_DIR
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.planning.plan_io import plan_file
from mavreg.sim.maneuver_run import fly_on_design_model

ROOT = Path(__file__).resolve().parents[1]


def _row(label, m):
    loop = m["segments"]["loop"]
    print(f"{label:>34}  {m['status']:>9}  {m['transverse_error_m']['max'] * 1e3:9.2f}"
          f"  {loop['transverse_error_m']['max'] * 1e3:9.2f}  {loop['attitude_error_deg']['max']:8.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=25)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--laps", type=int, default=3)
    args = ap.parse_args()
    vehicle = load_vehicle(PARAMS_DIR / "vehicles/mk_quadro.yaml")
    controller = load_controller(PARAMS_DIR / "controller/paper_lqr.yaml")
    maneuver = PARAMS_DIR / "maneuvers/barrel_roll.yaml"
    plan = plan_file(maneuver, vehicle, controller)
    rng = np.random.default_rng(args.seed)
    print(f"{'run':>34}  {'status':>9}  {'max mm':>9}  {'loop mm':>9}  {'loop deg':>8}")
    print("group 1: 0.6 m offset in each axis, inertia Monte Carlo (SD 0.0102/3 kg m^2)")
    J0 = np.array(vehicle.inertia_kg_m2)
    loops = []
    for i in range(args.runs + 1):
        J = J0 if i == 0 else np.maximum(J0 + rng.normal(0.0, 0.0102 / 3, 3), 1e-3)
        m = fly_on_design_model(plan, offset_m=(0.6, 0.6, 0.6), inertia_kg_m2=tuple(J)).metrics
        loops.append(m["segments"]["loop"]["transverse_error_m"]["max"])
        _row("nominal J" if i == 0 else "J = (" + ", ".join(f"{j:.4f}" for j in J) + ")", m)
    print(f"{'':>34}  loop max over all runs: {max(loops) * 1e3:.2f} mm")
    print(f"group 2: nominal start, 0.1 N rotor noise, {args.laps} laps")
    plan_laps = plan_file(maneuver, vehicle, controller, laps=args.laps)
    for sat in (None, 8.5, 7.0):
        m = fly_on_design_model(plan_laps, rotor_noise_sd_n=0.1, saturation_n=sat,
                                seed=args.seed).metrics
        _row(f"saturation {sat or 'none'} N (sat. {m.get('saturated_s', 0):.2f} s)", m)


if __name__ == "__main__":
    main()
