#!/usr/bin/env python3
"""Fly a maneuver with mavreg on the stock PX4 SITL (SIH) N times, through body rates and
thrust, and print the true path error of each flight (SIH's HIL_STATE_QUATERNION against the
plan in EKF2's frame), split into the estimate's own path error and EKF2's error.

    python -m scripts.px4.fly [--flights 5] [--maneuver FILE] [--airframe default|aggressive]
                              [--vehicle FILE] [--controller FILE] [--param NAME=VALUE ...] [--out DIR]
                              [--position-source gps|mocap]

Needs the PX4 SITL (``MAVREG_PX4_DIR``, or the shared autopilot directory beside the repository:
harness/px4_sitl.py).
Real time: about 1.5 minutes a flight. docs/autopilots.md quotes it.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

from harness.sitl_link import parse_param_items
from harness.px4_flight import AGGRESSIVE_PARAMS, CONTROLLER, VEHICLE, fly_on_px4
from harness.px4_sitl import POSITION_SOURCES

REPO = Path(__file__).resolve().parents[2]
AIRFRAMES = {"default": {}, "aggressive": AGGRESSIVE_PARAMS}


def _cm(v) -> str:
    return f"{100 * v:.1f}" if isinstance(v, float) else "n/a"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--flights", type=int, default=5)
    p.add_argument("--maneuver", default=str(REPO / "mavreg/params/maneuvers/figure_eight.yaml"))
    p.add_argument("--airframe", choices=sorted(AIRFRAMES), default="default",
                   help="SIH's airframe: PX4's default (thrust-to-weight 2) or aggressive (SIH_T_MAX 12.5 N, "
                   "thrust-to-weight 5)")
    p.add_argument("--vehicle", default=str(VEHICLE))
    p.add_argument("--controller", default=str(CONTROLLER))
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a PX4 parameter set before each flight (repeatable)")
    p.add_argument("--position-source", choices=POSITION_SOURCES, default="gps",
                   help="EKF2's: SIH's GPS and barometer, or the truth fed back as motion capture (default: %(default)s)")
    p.add_argument("--instance", type=int, default=None, metavar="N",
                   help="PX4's instance, 0-9: its ports and its system id 1 + N (default: the first free one)")
    p.add_argument("--fly-arg", action="append", default=[], metavar="ARG", help="one more `mavreg fly` argument")
    p.add_argument("--out", default=None, help="keep the flights here (default: a temporary directory)")
    args = p.parse_args(argv)
    if args.instance is not None and not 0 <= args.instance <= 9:
        p.error(f"--instance {args.instance}: want 0 to 9")
    params = {**AIRFRAMES[args.airframe], **parse_param_items(p, args.param)}
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mavreg-px4-"))
    ok = 0
    print("| flight | result | maneuver max (cm) | RMS (cm) | estimate's path error max (cm) | EKF2 error max (cm) "
          "| touchdown (m/s) |")
    print("|---|---|---|---|---|---|---|")
    for k in range(1, args.flights + 1):
        s = fly_on_px4(Path(args.maneuver), root / f"flight{k}", Path(args.vehicle), Path(args.controller),
                       params=params, extra_args=tuple(args.fly_arg), position_source=args.position_source,
                       instance=args.instance)
        gt = s.get("px4_truth") or {}
        ok += s["result"] == "ok"
        why = "" if s["result"] == "ok" else ": " + str(s.get("reason", ""))[:90]
        print(f"| {k} | {s['result']}{why} | {_cm(gt.get('max_m'))} | {_cm(gt.get('rms_m'))} | "
              f"{_cm(gt.get('estimate_max_m'))} | {_cm(gt.get('ekf_error_max_m'))} | "
              f"{s.get('touchdown_speed_m_s')} |", flush=True)
    print(f"\n{ok} of {args.flights} ok; flights in {root}")
    (root / "runs.json").write_text(json.dumps({"ok": ok, "flights": args.flights}))
    return 0 if ok == args.flights else 1


if __name__ == "__main__":
    sys.exit(main())
