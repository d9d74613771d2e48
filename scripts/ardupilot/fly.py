#!/usr/bin/env python3
"""Fly a maneuver with mavreg on the stock ArduCopter SITL N times, through body rates and
thrust, and print the true path error of each flight (the SITL's SIM_STATE) and a summary.

    python -m scripts.ardupilot.fly [--flights 5] [--maneuver FILE] [--out DIR] [--param NAME=VALUE ...]
                                    [--position-source gps|vicon|mocap] [--vehicle FILE] [--controller FILE]

Needs the SITL (``MAVREG_ARDUPILOT_DIR``; harness/ardupilot_sitl.py). Real time: about
2 minutes a flight (EKF start, take-off, maneuver, landing). docs/autopilots.md quotes it.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from harness.sitl_link import parse_param_items
from harness.ardupilot_flight import fly_on_ardupilot
from harness.ardupilot_sitl import POSITION_SOURCES

REPO = Path(__file__).resolve().parents[2]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--flights", type=int, default=5)
    p.add_argument("--maneuver", default=str(REPO / "mavreg/params/maneuvers/barrel_roll.yaml"))
    p.add_argument("--out", default=None, help="keep the flights here (default: a temporary directory)")
    p.add_argument("--control-rate-hz", type=float, default=200.0)
    p.add_argument("--vehicle", default=None, help="another vehicle file (default: the harness's, "
                   "mavreg/params/vehicles/ardupilot_freestyle.yaml)")
    p.add_argument("--controller", default=None, help="another controller file (default: the position "
                   "source's, freestyle.yaml or, for mocap, freestyle_mocap.yaml)")
    p.add_argument("--position-source", choices=POSITION_SOURCES, default="gps",
                   help="where ArduCopter's EKF3 takes its position from: its GPS, the SITL's simulated "
                   "Vicon, or the harness's motion-capture feed at 100 Hz (default: %(default)s)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="an ArduPilot parameter set before each flight (repeatable; an experiment's)")
    args = p.parse_args(argv)
    params = parse_param_items(p, args.param)
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mavreg-ardupilot-"))
    ok = 0
    print("| flight | result | loop max (cm) | all max (cm) | all RMS (cm) | touchdown (m/s) |")
    print("|---|---|---|---|---|---|")
    extra = () if args.vehicle is None else ("--vehicle-params", args.vehicle)
    for k in range(1, args.flights + 1):
        s = fly_on_ardupilot(Path(args.maneuver), root / f"flight{k}", args.control_rate_hz, params=params,
                             extra_args=extra,
                             position_source=args.position_source, controller=args.controller)
        gt = s.get("ardupilot_truth") or {}
        loop = (gt.get("segments") or {}).get("loop") or {}
        cm = (lambda v: f"{100 * v:.1f}" if isinstance(v, float) else "n/a")   # noqa: E731
        ok += s["result"] == "ok"
        print(f"| {k} | {s['result']}{'' if s['result'] == 'ok' else ': ' + s['reason'][:80]} | "
              f"{cm(loop.get('max_m'))} | {cm(gt.get('max_m'))} | {cm(gt.get('rms_m'))} | "
              f"{s.get('touchdown_speed_m_s')} |", flush=True)
    print(f"\n{ok} of {args.flights} ok; flights in {root}")
    (root / "runs.json").write_text(json.dumps({"ok": ok, "flights": args.flights}))
    return 0 if ok == args.flights else 1


if __name__ == "__main__":
    sys.exit(main())
