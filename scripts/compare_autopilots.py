#!/usr/bin/env python3
"""Fly a maneuver through the autopilot's OWN position controller (PX4 OFFBOARD, ArduCopter
GUIDED) as SET_POSITION_TARGET_LOCAL_NED set-points of the plan's nominal in time, and print its
true path error: the baseline mavreg is compared with (issue 29, item 4).

    python -m scripts.compare_autopilots [--runs px4:figure_eight,px4:slalom,ardupilot:figure_eight]
        [--flights N] [--out DIR] [--px4-vehicle FILE] [--px4-instance 7] [--param px4:NAME=VALUE ...]

Each flight starts a fresh SITL (PX4 SIH and ArduCopter from the shared autopilot directory
beside the repository; tests/helpers says where they are looked for), real time, one at
a time: about 1.5 min (PX4 figure-eight) to 3 min (ArduCopter). Prints one markdown row per
flight (maneuver max and RMS true path error, EKF error), writes ``results.json`` and one
figure per maneuver (top view of the nominal and every flown track) into ``--out``.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

from mavreg.experiments.autopilot_baseline import FEEDFORWARDS

REPO = Path(__file__).resolve().parents[1]
MANEUVERS = REPO / "mavreg" / "params" / "maneuvers"
CONTROLLER = REPO / "mavreg" / "params" / "controller" / "realistic.yaml"
ARDUPILOT_VEHICLE = REPO / "mavreg" / "params" / "vehicles" / "ardupilot_freestyle.yaml"
PX4_VEHICLE = REPO / "mavreg" / "params" / "vehicles" / "px4_sih.yaml"
DEFAULT_RUNS = "px4:figure_eight,px4:slalom,ardupilot:figure_eight"
AUTOPILOTS = ("px4", "ardupilot")


def _runs(text: str) -> list[tuple[str, Path]]:
    runs = []
    for item in (i.strip() for i in text.split(",") if i.strip()):
        autopilot, _, maneuver = item.partition(":")
        if autopilot not in AUTOPILOTS or not maneuver:
            raise ValueError(f"--runs {item!r}: want AUTOPILOT:MANEUVER with AUTOPILOT one of {', '.join(AUTOPILOTS)}")
        path = Path(maneuver) if maneuver.endswith(".yaml") else MANEUVERS / f"{maneuver}.yaml"
        if not path.is_file():
            raise ValueError(f"--runs {item!r}: no maneuver file {path}")
        runs.append((autopilot, path))
    if not runs:
        raise ValueError("--runs is empty")
    return runs


def _params(items: list[str]) -> dict[str, dict]:
    out: dict[str, dict] = {a: {} for a in AUTOPILOTS}
    for item in items:
        autopilot, _, rest = item.partition(":")
        name, _, value = rest.partition("=")
        try:
            out[autopilot][name.strip()] = float(value)
        except (KeyError, ValueError):
            raise ValueError(f"--param {item!r}: want AUTOPILOT:NAME=VALUE (AUTOPILOT px4 or ardupilot, "
                             "VALUE a number)") from None
    return out


def _cm(v) -> str:
    return f"{100 * v:.1f}" if isinstance(v, (int, float)) and v == v else "n/a"


def fly_one(autopilot: str, maneuver: Path, out: Path, vehicle: Path, params: dict, instance: int,
            feedforward: str, position_source: str = "gps") -> dict:
    """One flight; a row of the table (``result`` names the failure in one line)."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.planning.plan_io import plan_file
    from harness.autopilot_baseline_flight import fly_ardupilot_baseline, fly_px4_baseline
    from harness.sitl_link import SitlError
    plan = plan_file(maneuver, load_vehicle(vehicle), load_controller(CONTROLLER))
    row = {"autopilot": autopilot, "maneuver": maneuver.stem, "feedforward": feedforward, "out": str(out),
           "load_before": os.getloadavg()[0]}
    try:
        if autopilot == "px4":
            s = fly_px4_baseline(plan, maneuver, out, vehicle, CONTROLLER, params, instance=instance,
                                 feedforward=feedforward, position_source=position_source)
        else:
            s = fly_ardupilot_baseline(plan, maneuver, out, CONTROLLER, params, feedforward=feedforward)
    except (SitlError, OSError) as exc:
        return {**row, "result": f"failed: {str(exc).splitlines()[0][:160]}"}
    truth = s.get("truth") or {}
    return {**row, "result": s["result"], "max_m": truth.get("max_m"), "rms_m": truth.get("rms_m"),
            "samples": truth.get("samples"), "ekf_error_max_m": truth.get("ekf_error_max_m"),
            "estimate_max_m": truth.get("estimate_max_m"),
            "segments": {k: v.get("max_m") for k, v in (truth.get("segments") or {}).items()},
            "params_set": s.get("params_set"), "load_after": os.getloadavg()[0]}


def _quiet_machine(max_load: float, wait_s: float) -> None:
    """Wait until the load average is below ``max_load``, at most ``wait_s`` (polled: the load
    is no message to wait on)."""
    deadline = time.monotonic() + wait_s
    while os.getloadavg()[0] >= max_load and time.monotonic() < deadline:
        time.sleep(5.0)


def markdown_row(k: int, row: dict) -> str:
    return (f"| {row['autopilot']} | {row['maneuver']} | {row['feedforward']} | {k} | {row['result']} | {_cm(row.get('max_m'))} | "
            f"{_cm(row.get('rms_m'))} | {_cm(row.get('estimate_max_m'))} | {_cm(row.get('ekf_error_max_m'))} | "
            f"{row['load_before']:.2f} |")


def figures(rows: list[dict], root: Path, vehicles: dict) -> list[Path]:
    """One PNG per maneuver: the nominal's top view and every flown track."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.planning.plan_io import plan_file
    from harness.autopilot_baseline_flight import flown_track
    written = []
    for maneuver in sorted({r["maneuver"] for r in rows}):
        mine = [r for r in rows if r["maneuver"] == maneuver and r.get("max_m") is not None]
        if not mine:
            continue
        plan = plan_file(MANEUVERS / f"{maneuver}.yaml", load_vehicle(vehicles[mine[0]["autopilot"]]),
                         load_controller(CONTROLLER))
        north, east = plan.x[:, 0], plan.x[:, 1]
        along = np.ptp(north) > 3.0 * np.ptp(east)    # a long course (the slalom): north across the page
        fig, ax = plt.subplots(figsize=(12, 4.5) if along else (8, 7))

        def draw(n, e, **kw):
            return ax.plot(n, e, **kw) if along else ax.plot(e, n, **kw)
        draw(north, east, color="k", lw=2.5, label="nominal")
        for r in mine:
            track = flown_track(Path(r["out"]))
            draw(track[:, 0], track[:, 1], lw=1, label=f"{Path(r['out']).name}: max {_cm(r['max_m'])} cm")
        ax.set_xlabel("north (m)" if along else "east (m)")
        ax.set_ylabel("east (m)" if along else "north (m)")
        if not along:
            ax.set_aspect("equal")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
        ax.set_title(f"{maneuver}: the autopilot's own position controller (true position, top view)")
        path = root / f"{maneuver}.png"
        fig.savefig(path, dpi=120, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    return written


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", default=DEFAULT_RUNS, help="AUTOPILOT:MANEUVER[,...] (default: %(default)s)")
    p.add_argument("--flights", type=int, default=1, help="flights of each run (default: %(default)s)")
    p.add_argument("--out", default=None, help="keep the flights here (default: a temporary directory)")
    p.add_argument("--px4-vehicle", default=str(PX4_VEHICLE), help="vehicle file the PX4 runs are planned "
                   "with (default: %(default)s)")
    p.add_argument("--px4-instance", type=int, default=7, help="PX4 SITL instance: ports 14540+i, 19410+i "
                   "(default: %(default)s)")
    p.add_argument("--feedforward", choices=FEEDFORWARDS, default="kinematic",
                   help="the maneuver's acceleration set-point: the nominal's kinematic acceleration, or the "
                   "part its thrust gives (kinematic less the nominal's drag; the autopilots model no drag) "
                   "(default: %(default)s)")
    p.add_argument("--px4-position-source", choices=("gps", "mocap"), default="gps",
                   help="EKF2's on PX4: SIH's GPS and barometer, or the harness's motion-capture feed "
                   "(harness/px4_sitl.py) (default: %(default)s)")
    p.add_argument("--max-load", type=float, default=1.5, help="wait before each flight until the 1-minute "
                   "load average is below this (real time: a loaded machine slows the SITL) (default: %(default)s)")
    p.add_argument("--load-wait-s", type=float, default=600.0, help="fly anyway after waiting this long "
                   "(the row says the load) (default: %(default)s)")
    p.add_argument("--param", action="append", default=[], metavar="AUTOPILOT:NAME=VALUE",
                   help="an autopilot parameter set before each flight on top of the baseline's (repeatable)")
    args = p.parse_args(argv)
    try:
        runs, params = _runs(args.runs), _params(args.param)
        if args.flights < 1:
            raise ValueError(f"--flights must be at least 1, got {args.flights}")
    except ValueError as exc:
        p.error(str(exc))
    vehicles = {"px4": Path(args.px4_vehicle), "ardupilot": ARDUPILOT_VEHICLE}
    if any(a == "px4" for a, _ in runs) and not vehicles["px4"].is_file():
        p.error(f"no PX4 vehicle file {vehicles['px4']}: pass --px4-vehicle FILE")
    from mavreg.config.loader import ConfigError
    from mavreg.config.vehicle import load_vehicle
    for autopilot in {a for a, _ in runs}:
        try:
            load_vehicle(vehicles[autopilot])
        except ConfigError as exc:
            p.error(str(exc).splitlines()[0])
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mavreg-compare-"))
    root.mkdir(parents=True, exist_ok=True)
    print(f"{datetime.datetime.now().isoformat(timespec='minutes')}, {os.cpu_count()} cores; flights in {root}\n")
    print("| autopilot | maneuver | acceleration fed forward | flight | result | true max (cm) | true RMS (cm) "
          "| estimate's path error max (cm) | EKF error max (cm) | load before |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    rows = []
    for autopilot, maneuver in runs:
        for k in range(1, args.flights + 1):
            _quiet_machine(args.max_load, args.load_wait_s)
            row = fly_one(autopilot, maneuver, root / f"{autopilot}_{maneuver.stem}_{args.feedforward}_{k}",
                          vehicles[autopilot], params[autopilot], args.px4_instance, args.feedforward,
                          args.px4_position_source)
            rows.append(row)
            print(markdown_row(k, row), flush=True)
            (root / "results.json").write_text(json.dumps(rows, indent=1, default=float))
    for path in figures(rows, root, vehicles):
        print(f"figure: {path}")
    return 0 if all(r["result"] == "ok" for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
