#!/usr/bin/env python3
"""Split one ArduCopter flight's true path error into what the controller saw and what the
estimator got wrong, along the maneuver's arc length.

    python -m scripts.ardupilot.decompose FLIGHT_DIR [--bins 40]

FLIGHT_DIR is one flight of ``scripts.ardupilot.fly --out`` (its ``flight.tlog``, which holds the
EKF origin the daemon asked for, ``summary.json``, and the harness's ``truth_origin.json`` when it is
there: the local frame's origin, which with motion capture is not the EKF origin). Over the maneuver's window it projects on the plan

- (a) the EKF's position (``LOCAL_POSITION_NED``, what mavreg regulates on),
- (c) the true position (``SIM_STATE`` about the EKF origin),

and, at equal arc length, (b) = (c) - (a): the transverse part of the estimate's error (the
along-track part does not move a point off the path). Each is a vector in the path's normal
plane (m1, m2); the script prints their largest norms per segment and per bin of s, so that the
bins where the truth peaks show which part peaks there. Timing between the two streams does not
enter: both are compared at the same s.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

REPO = Path(__file__).resolve().parents[2]


def _window(summary: dict) -> tuple[float, float]:
    events = summary.get("events") or []
    phase = [(e["time_s"], e.get("phase")) for e in events if e.get("kind") == "phase" and e.get("time_s") is not None]
    begin = next(t for t, p in phase if p == "maneuver")
    end = next((t for t, p in phase if t > begin and p != "maneuver"), math.inf)
    return begin, end


def _estimates(tlog: Path):
    """(vehicle time s, EKF NED position) of every LOCAL_POSITION_NED of the autopilot, and
    its GPS_GLOBAL_ORIGIN."""
    from pymavlink import mavutil
    log = mavutil.mavlink_connection(str(tlog), dialect="common")
    t, p, origin = [], [], None
    while (m := log.recv_match(type=["LOCAL_POSITION_NED", "GPS_GLOBAL_ORIGIN"])) is not None:
        if m.get_type() == "GPS_GLOBAL_ORIGIN":
            origin = m
        elif m.get_srcComponent() == 1:
            t.append(m.time_boot_ms / 1000.0)
            p.append((m.x, m.y, m.z))
    return np.array(t), np.array(p), origin


def normal_errors(plan, positions) -> tuple[np.ndarray, np.ndarray]:
    """(s, the offset from the path in its normal plane (K, 2): components along m1, m2)."""
    from mavreg.geometry.projection import Projector
    proj = Projector(plan.path)
    s_out, e_out = [], []
    for i, p in enumerate(np.asarray(positions, dtype=float)):
        pr = proj.reset(p, 0.0) if i == 0 else proj.update(p)
        if 0.0 < pr.s < plan.length_m:
            d = p - pr.point.position
            s_out.append(pr.s)
            e_out.append(pr.point.frame[:, 1:].T @ d)
    return np.array(s_out), np.array(e_out).reshape(-1, 2)


def _resample(s: np.ndarray, e: np.ndarray, grid: np.ndarray) -> np.ndarray:
    order = np.argsort(s)
    s, e = s[order], e[order]
    keep = np.concatenate([[True], np.diff(s) > 0])
    return np.stack([np.interp(grid, s[keep], e[keep, k]) for k in range(e.shape[1])], axis=1)


def decompose(flight: Path, bins: int = 40) -> dict:
    """The three errors of one flight: per segment and per bin of s (max of the norms, m)."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.planning.plan_io import plan_file
    from harness.ardupilot_flight import CONTROLLER, VEHICLE, _truth_samples

    summary = json.loads((flight / "summary.json").read_text())
    begin, end = _window(summary)
    maneuver = Path(summary.get("maneuver_file") or REPO / "mavreg/params/maneuvers/barrel_roll.yaml")
    plan = plan_file(maneuver, load_vehicle(VEHICLE), load_controller(CONTROLLER))
    t_est, p_est, origin = _estimates(flight / "flight.tlog")
    if (flight / "truth_origin.json").is_file():    # the harness's: the local frame's origin
        origin = SimpleNamespace(**json.loads((flight / "truth_origin.json").read_text()))
    t_true, p_true, _, _ = _truth_samples(flight / "flight.tlog", origin)
    sel_e = (t_est >= begin) & (t_est <= end)
    sel_t = (t_true >= begin) & (t_true <= end)
    s_a, e_a = normal_errors(plan, p_est[sel_e])
    s_c, e_c = normal_errors(plan, p_true[sel_t])
    grid = np.linspace(max(s_a.min(), s_c.min()), min(s_a.max(), s_c.max()), 4000)
    a, c = _resample(s_a, e_a, grid), _resample(s_c, e_c, grid)
    b = c - a
    norms = {"a_estimate_path": np.linalg.norm(a, axis=1), "b_truth_minus_estimate": np.linalg.norm(b, axis=1),
             "c_truth_path": np.linalg.norm(c, axis=1)}
    out: dict = {"segments": {}, "bins": []}
    for name, lo, hi in plan.segments:
        m = (grid >= lo) & (grid < hi)
        out["segments"][name] = {k: float(v[m].max()) if m.any() else None for k, v in norms.items()}
    edges = np.linspace(grid[0], grid[-1], bins + 1)
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (grid >= lo) & (grid < hi)
        row = {"s_m": round(float(lo), 2), "segment": plan.path.segment_at(float(lo)).name}
        row.update({k: float(v[m].max()) for k, v in norms.items()})
        out["bins"].append(row)
    # the estimate's error by components at the truth's worst point
    k = int(np.argmax(norms["c_truth_path"]))
    out["worst"] = {"s_m": float(grid[k]), "a_m": a[k].tolist(), "b_m": b[k].tolist(), "c_m": c[k].tolist()}
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("flight", type=Path)
    p.add_argument("--bins", type=int, default=40)
    args = p.parse_args(argv)
    r = decompose(args.flight, args.bins)
    cm = lambda v: f"{100 * v:5.1f}" if v is not None else "  n/a"  # noqa: E731
    print("| segment | (a) estimate's path error | (b) truth - estimate | (c) true path error |  (max, cm)")
    for name, v in r["segments"].items():
        print(f"| {name} | {cm(v['a_estimate_path'])} | {cm(v['b_truth_minus_estimate'])} | {cm(v['c_truth_path'])} |")
    print("\n   s (m)  segment   (a)    (b)    (c)")
    for row in r["bins"]:
        print(f"  {row['s_m']:6.2f}  {row['segment']:8s} {cm(row['a_estimate_path'])}  "
              f"{cm(row['b_truth_minus_estimate'])}  {cm(row['c_truth_path'])}")
    w = r["worst"]
    print(f"\nworst true point s = {w['s_m']:.2f} m: (a) {np.round(100 * np.array(w['a_m']), 1)} cm, "
          f"(b) {np.round(100 * np.array(w['b_m']), 1)} cm, (c) {np.round(100 * np.array(w['c_m']), 1)} cm "
          "(components along the path's normals m1, m2)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
