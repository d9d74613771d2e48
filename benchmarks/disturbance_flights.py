"""The barrel roll against drag, wind and a thrust loss, with and without the disturbance observer.

    python benchmarks/disturbance_flights.py [--realtime] [--cases NAME ...] [--out DIR]

Each case is ``mavreg fly params/maneuvers/barrel_roll.yaml`` on the bundled emulator
(lockstep by default, ``--realtime`` for real time) with one of its presets
(docs/firmware_sim.md): ``realistic`` (RotorPy-sized drag), ``thrust90``, ``wind3`` and
``wind6`` (from the north unless the case says ``@DEG``), flown with
params/controller/realistic.yaml (observer on), with the observer off (``-off``), or with a
vehicle file calibrated by ``mavreg identify`` on the first realistic flight (``-cal``).
Prints one row per case, judged on the emulator's ground truth: the result (and the first
bound violated), the loop's maximum true transverse error, speed error and overspeed, the
worst segment, and the observer's final estimate. Figures: docs/robustness.md.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from mavreg.config.paths import PARAMS_DIR

ROOT = Path(__file__).resolve().parents[1]
BARREL = PARAMS_DIR / "maneuvers/barrel_roll.yaml"
CONTROLLER = PARAMS_DIR / "controller/realistic.yaml"
DEFAULT_CASES = ("realistic", "realistic-off", "realistic-cal", "thrust90", "thrust90-off",
                 *(f"wind3@{d}" for d in range(0, 360, 45)), "wind3@90-off", "wind6@0")


def _mavreg(*args) -> int:
    return subprocess.run([sys.executable, "-m", "mavreg.cli.main", *args], cwd=ROOT,
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=900).returncode


def fly_case(case: str, out: Path, realtime: bool, calibrated: Path | None) -> dict:
    """Fly one case into ``out``; its summary row."""
    name, _, variant = case.partition("-")
    preset, _, wind_from = name.partition("@")
    args = ["fly", str(BARREL), "--out", str(out), f"--emulator-arg=--world={preset}"]
    if wind_from:
        args.append(f"--emulator-arg=--wind-from-deg={wind_from}")
    if not realtime:
        args.append("--lockstep")
    if variant == "off":
        off = out.parent / "observer_off.yaml"
        off.write_text(CONTROLLER.read_text().replace("disturbance:\n  enabled: true",
                                                       "disturbance:\n  enabled: false"))
        args += ["--controller", str(off)]
    elif variant == "cal":
        if calibrated is None:
            return {"case": case, "result": "no calibration (fly 'realistic' first)"}
        args += ["--vehicle-params", str(calibrated)]
    elif variant:
        raise SystemExit(f"disturbance_flights: unknown variant {variant!r} in case {case!r}")
    code = _mavreg(*args)
    try:
        s = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return {"case": case, "result": f"no summary (exit {code})"}
    row = {"case": case, "result": s["result"]}
    fail = s.get("failure") or {}
    if fail:
        where = f" at s={fail['s_m']:.1f} m" if fail.get("s_m") is not None else ""
        row["result"] += f" ({fail['bound']} in {fail['phase']}{where})"
    gt = s.get("ground_truth") or {}
    seg = gt.get("segments") or {}
    loop = seg.get("loop") or {}
    row.update(loop_cm=None if loop.get("max_m") is None else 100 * loop["max_m"],
               speed_m_s=loop.get("max_speed_error_m_s"), over_m_s=loop.get("max_overspeed_m_s"))
    if seg:
        name, worst = max(seg.items(), key=lambda kv: kv[1].get("max_m") or 0.0)
        row["worst"] = f"{name} {100 * worst['max_m']:.1f}"
    est = (s.get("status") or {}).get("disturbance")
    row["estimate"] = "off" if est is None else (
        f"{est['drag_n_s_per_m'][0]:.2f}, {est['drag_n_s_per_m'][1]:.2f}, {est['force_ned_n'][0]:.2f}, "
        f"{est['force_ned_n'][1]:.2f}, {est['thrust_scale']:.3f}")
    return row


def _f(v, fmt="{:.2f}"):
    return "–" if v is None else fmt.format(v)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--realtime", action="store_true", help="fly in real time (default: lockstep)")
    p.add_argument("--cases", nargs="+", default=list(DEFAULT_CASES), metavar="CASE",
                   help="PRESET[@WIND_FROM_DEG][-off|-cal] (default: all of the table)")
    p.add_argument("--out", type=Path, default=None, help="keep the flights here (default: a temporary directory)")
    a = p.parse_args(argv)
    root = a.out or Path(tempfile.mkdtemp(prefix="mavreg-disturbance-"))
    root.mkdir(parents=True, exist_ok=True)
    calibrated = None
    print("| case | result | loop max (cm) | loop speed error (m/s) | overspeed (m/s) | worst segment (cm) "
          "| estimate c_xy, c_z, F_n, F_e, k |")
    print("|---|---|---|---|---|---|---|")
    for case in a.cases:
        out = root / case.replace("@", "_from")
        row = fly_case(case, out, a.realtime, calibrated)
        if case == "realistic" and (out / "flight.tlog").exists():
            cal = root / "calibrated.yaml"
            if _mavreg("identify", str(out), "--write-vehicle", str(cal)) == 0:
                calibrated = cal
        print(f"| {row['case']} | {row['result']} | {_f(row.get('loop_cm'))} | {_f(row.get('speed_m_s'))} "
              f"| {_f(row.get('over_m_s'))} | {row.get('worst', '–')} | {row.get('estimate', '–')} |", flush=True)
    print(f"flights in {root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
