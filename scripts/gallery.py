"""Make docs/gallery.md: every maneuver of params/maneuvers/, planned and flown.

For each file: plan it (params/controller/design.yaml), draw its path with the nominal body
axes along it and its plan figures (speed, thrust, rotor forces against s), fly it on the
design model from its nominal entry (`mavreg simulate`'s flight), and with ``--sitl`` fly it
through the daemon against firmware_sim in lockstep: the ideal world with the paper's
weights (design.yaml) and the realistic world (20 ms rotor lag, link delay, estimate noise,
drag) with realistic.yaml. Writes docs/gallery/<name>.png and docs/gallery.md.

    python scripts/gallery.py [--sitl] [--only NAME ...]

The SITL flights take about half a minute each (14 with --sitl); run them on a quiet
machine (lockstep keeps the results independent of the load, not the time).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from mavreg.cli.common import DEFAULT_VEHICLE, DESIGN_CONTROLLER, REAL_CONTROLLER  # noqa: E402
from mavreg.config.controller import load_controller  # noqa: E402
from mavreg.config.maneuver import load_maneuver  # noqa: E402
from mavreg.config.vehicle import load_vehicle  # noqa: E402
from mavreg.maneuver.plan import plan_spec  # noqa: E402
from mavreg.model.mixer import Mixer  # noqa: E402
from mavreg.sim.maneuver_run import fly_on_design_model  # noqa: E402

LIBRARY = ROOT / "params" / "maneuvers"
OUT = ROOT / "docs" / "gallery"
ORDER = ("barrel_roll", "forward_loop", "split_s", "immelmann", "figure_eight",
         "climbing_helix", "slalom")


def draw(plan, png: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 6.5))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    fast = plan.speed_m_s > 0.5 * plan.speed_m_s.max()     # the maneuver, not its slow ends
    pos = plan.x[fast, :3]
    ax.plot(pos[:, 1], pos[:, 0], -pos[:, 2], "k-", lw=0.8)
    s_fast = plan.s[fast]
    picks = np.flatnonzero(fast)[np.searchsorted(s_fast, np.arange(s_fast[0], s_fast[-1], 0.8))]
    span = float(np.ptp(pos, axis=0).max())
    arm = 0.06 * span
    for i in picks:
        R = plan.R[i]
        p = plan.x[i, :3]
        for col, colour in ((0, "tab:red"), (2, "tab:blue")):      # nose, thrust axis (down)
            d = R[:, col] * (arm if col == 0 else -0.7 * arm)        # thrust drawn up
            ax.plot([p[1], p[1] + d[1]], [p[0], p[0] + d[0]], [-p[2], -p[2] - d[2]], colour, lw=1)
    centre = (pos.max(axis=0) + pos.min(axis=0)) / 2
    half = 0.55 * span
    ax.set_xlim(centre[1] - half, centre[1] + half)
    ax.set_ylim(centre[0] - half, centre[0] + half)
    ax.set_zlim(-centre[2] - half, -centre[2] + half)
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_zlabel("altitude (m)")
    ax.set_title(f"{plan.name} above half its top speed: nose (red) and thrust (blue) every 0.8 m",
                 fontsize=9)
    mixer = Mixer(plan.vehicle.arm_length_m, plan.vehicle.drag_torque_ratio_m)
    rotors = plan.u @ mixer.inverse.T
    a1 = fig.add_subplot(3, 2, 2)
    a1.plot(plan.s, plan.speed_m_s, lw=0.8)
    a1.set_ylabel("speed (m/s)")
    a2 = fig.add_subplot(3, 2, 4, sharex=a1)
    a2.plot(plan.s, plan.u[:, 0], lw=0.8)
    a2.set_ylabel("thrust (N)")
    a3 = fig.add_subplot(3, 2, 6, sharex=a1)
    a3.plot(plan.s, rotors, lw=0.7)
    a3.axhline(plan.vehicle.max_rotor_thrust_n, color="k", ls="--", lw=0.6)
    a3.set_ylabel("rotor forces (N)")
    a3.set_xlabel("arc length s (m)")
    for sp in plan.path.spans:
        for a in (a1, a2, a3):
            a.axvline(sp.s_start_m, color="0.85", lw=0.5)
    fig.tight_layout()
    fig.savefig(png, dpi=90)
    plt.close(fig)


def design_flight(plan) -> dict:
    run = fly_on_design_model(plan)
    m = run.metrics
    mixer = Mixer(plan.vehicle.arm_length_m, plan.vehicle.drag_torque_ratio_m)
    return {"status": m["status"], "transverse_mm": 1e3 * m["transverse_error_m"]["max"],
            "attitude_deg": m["attitude_error_deg"]["max"],
            "peak_rotor_n": float(np.max(run.result.rotor_command_n)),
            "nominal_peak_rotor_n": float(np.max(plan.u @ mixer.inverse.T))}


def sitl_flight(maneuver: Path, world: str, controller: Path) -> dict:
    with tempfile.TemporaryDirectory() as out:
        proc = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "fly", str(maneuver),
                               "--lockstep", "--world", world, "--controller", str(controller),
                               "--out", out], capture_output=True, text=True, timeout=900)
        try:
            summary = json.loads((Path(out) / "summary.json").read_text())
        except (OSError, ValueError):
            return {"ok": False, "error": (proc.stderr or proc.stdout).strip().splitlines()[-1:]}
    truth = summary["ground_truth"] or {}
    return {"ok": proc.returncode == 0, "transverse_cm": 100 * truth.get("max_m", float("nan")),
            "attitude_deg": truth.get("max_deg", float("nan")),
            "controller": summary["controller_metrics"], "reason": summary["reason"]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sitl", action="store_true", help="also fly each through the daemon in lockstep SITL")
    p.add_argument("--only", nargs="+", metavar="NAME", help="these maneuvers only")
    args = p.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    vehicle = load_vehicle(DEFAULT_VEHICLE)
    controller = load_controller(DESIGN_CONTROLLER)
    rows = []
    for name in args.only or ORDER:
        path = LIBRARY / f"{name}.yaml"
        spec = load_maneuver(path)
        plan = plan_spec(spec, vehicle, controller)
        draw(plan, OUT / f"{name}.png")
        row = {"name": name, "description": spec.description, "yaw_mode": spec.yaw.mode,
               "length_m": plan.length_m, "duration_s": plan.duration_s,
               "max_pitch_deg": float(np.degrees(np.abs(plan.x[:, 4]).max())),
               "design": design_flight(plan)}
        if args.sitl:
            row["sitl_ideal"] = sitl_flight(path, "ideal", DESIGN_CONTROLLER)
            row["sitl_realistic"] = sitl_flight(path, "realistic", REAL_CONTROLLER)
        print(json.dumps(row), flush=True)
        rows.append(row)
    (OUT / "results.json").write_text(json.dumps(rows, indent=2))
    if not args.only:
        (ROOT / "docs" / "gallery.md").write_text(markdown(rows, args.sitl))
    return 0


def _cell(r: dict | None) -> str:
    if r is None:
        return "not flown"
    if not r["ok"]:
        return f"failed: {r['reason']}"
    c = r["controller"]
    return (f"{r['transverse_cm']:.2f} cm, {c['attitude_error_deg']['max']:.1f} deg, "
            f"{c['rotor_command_n']['max']:.1f} N")


def markdown(rows, sitl: bool) -> str:
    lines = ["# Maneuver gallery", "",
             "Every file of `params/maneuvers/`, planned with `params/controller/design.yaml` (the",
             "paper's weights on the SO(3) attitude error) on the MK-Quadro (12 N rotors), and flown.",
             "Made by `python scripts/gallery.py --sitl`; each figure shows the path (where the speed is",
             "above half its top) with the nose (red) and the thrust axis (blue) every 0.8 m, and the plan's speed,",
             "thrust and rotor forces against arc length.", "",
             "- **design model**: `mavreg simulate FILE` (1 kHz control, ideal rotors, from the",
             "  nominal entry): maximum transverse and attitude error over the whole maneuver.",
             "- **SITL ideal**: `mavreg fly FILE --lockstep --world ideal --controller",
             "  params/controller/design.yaml`: the daemon against firmware_sim, true state, no delay.",
             "- **SITL realistic**: `mavreg fly FILE --lockstep` (the defaults: the realistic world's",
             "  20 ms rotor lag, link delay and loss, estimator noise and drag; realistic.yaml).",
             "  SITL columns: the true (ground-truth) maximum transverse error over the maneuver",
             "  (run-up to run-out), the regulator's maximum attitude error (against the nominal it",
             "  flies: the drag compensation turns it by up to 15 deg in the realistic world) and",
             "  the peak rotor command.", "",
             "| maneuver | yaw mode | length, time | max pitch | peak rotor (plan) | design model | "
             "SITL ideal | SITL realistic |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        d = r["design"]
        lines.append(
            f"| [{r['name']}](#{r['name'].replace('_', '-')}) | {r['yaw_mode']} | "
            f"{r['length_m']:.0f} m, {r['duration_s']:.0f} s | {r['max_pitch_deg']:.0f} deg | "
            f"{d['nominal_peak_rotor_n']:.1f} N | {d['transverse_mm']:.3f} mm, {d['attitude_deg']:.4f} deg | "
            f"{_cell(r.get('sitl_ideal')) if sitl else 'not flown'} | "
            f"{_cell(r.get('sitl_realistic')) if sitl else 'not flown'} |")
    for r in rows:
        lines += ["", f"## {r['name']}", "", r["description"] or "", "",
                  f"![{r['name']}](gallery/{r['name']}.png)"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
