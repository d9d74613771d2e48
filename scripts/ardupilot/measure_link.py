#!/usr/bin/env python3
"""Measure what a stock ArduCopter SITL says on the ground (no flight).

HEARTBEAT fields, time to EKF origin and to passing pre-arm checks, parameters read by
name, achieved telemetry rates for requested 100/200/400 Hz, the time_boot_ms pairing of
ATTITUDE_QUATERNION and LOCAL_POSITION_NED, and its TIMESYNC answers. Prints one JSON
document. Needs the SITL (``MAVREG_ARDUPILOT_DIR``; see ``harness/ardupilot_sitl.py``).

    python scripts/ardupilot/measure_link.py [--frame freestyle]
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from harness.ardupilot_sitl import ArduPilotSitl, SitlError  # noqa: E402

PARAMS = ["GUID_OPTIONS", "GUID_TIMEOUT", "FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "DISARM_DELAY",
          "MOT_THST_HOVER", "MOT_THST_EXPO", "MOT_SPIN_MIN", "MOT_SPIN_ARM", "ATC_RAT_RLL_P",
          "ATC_RAT_RLL_I", "ATC_RAT_RLL_D", "ATC_RAT_PIT_P", "ATC_RAT_PIT_I", "ATC_RAT_PIT_D",
          "ATC_RAT_YAW_P", "ATC_RAT_YAW_I", "ATC_RAT_YAW_D", "ATC_INPUT_TC", "SCHED_LOOP_RATE",
          "ARMING_CHECK", "LAND_ALT_LOW", "FS_THR_ENABLE", "SR0_EXTRA1", "MAV1_EXTRA1", "BRD_BOOT_DELAY"]
IDS = {"ATTITUDE_QUATERNION": 31, "LOCAL_POSITION_NED": 32, "ATTITUDE": 30, "SIM_STATE": 108,
       "ODOMETRY": 331}


def collect(sitl, seconds: float) -> dict:
    """Messages of the kinds in IDS (and TIMESYNC) for ``seconds``: type -> [(arrival, msg)]."""
    got: dict = {k: [] for k in IDS}
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        m = sitl.recv(0.05)
        if m is not None and m.get_type() in got:
            got[m.get_type()].append((time.monotonic(), m))
    return got


def rates(sitl, hz: float, seconds: float = 4.0) -> dict:
    acks = {name: sitl.set_rate(i, hz) for name, i in IDS.items()}
    collect(sitl, 1.0)                        # settle
    got = collect(sitl, seconds)
    out = {"requested_hz": hz, "ack_results": acks}
    for name, rows in got.items():
        if len(rows) > 2:
            t_boot = np.array([getattr(m, "time_boot_ms", getattr(m, "time_usec", 0) // 1000)
                               for _, m in rows], float)
            out[name] = {"hz_host": round(len(rows) / seconds, 1),
                         "median_dt_ms": float(np.median(np.diff(t_boot)))}
        else:
            out[name] = {"hz_host": len(rows) / seconds}
    out["pairing"] = pairing(got["ATTITUDE_QUATERNION"], got["LOCAL_POSITION_NED"])
    return out


def pairing(att: list, pos: list) -> dict:
    """How ATTITUDE_QUATERNION and LOCAL_POSITION_NED times relate in arrival order."""
    pos_times = {m.time_boot_ms for _, m in pos}
    equal = sum(m.time_boot_ms in pos_times for _, m in att)
    merged = sorted([(a, 0, m) for a, m in att] + [(a, 1, m) for a, m in pos], key=lambda r: r[0])
    last_pos, gaps = None, []
    for _, kind, m in merged:
        if kind == 1:
            last_pos = m.time_boot_ms
        elif last_pos is not None:
            gaps.append(m.time_boot_ms - last_pos)
    g = np.array(gaps, float) if gaps else np.zeros(1)
    return {"attitudes": len(att), "positions": len(pos), "same_time_boot_ms": equal,
            "att_minus_latest_pos_ms": {"median": float(np.median(g)), "p95": float(np.percentile(g, 95)),
                                        "max": float(g.max()), "min": float(g.min())}}


def timesync(sitl, n: int = 20) -> dict:
    """Our requests (tc1 = 0) and its answers, against its time_boot_ms; and its own requests."""
    rows, own_requests = [], 0
    for _ in range(n):
        ts1 = time.monotonic_ns()
        sitl.conn.mav.timesync_send(0, ts1)
        end = time.monotonic() + 0.5
        last_boot_ms = None
        while time.monotonic() < end:
            m = sitl.recv(0.05)
            if m is None:
                continue
            if hasattr(m, "time_boot_ms"):
                last_boot_ms = m.time_boot_ms
            if m.get_type() == "TIMESYNC":
                if m.tc1 == 0:
                    own_requests += 1
                    continue
                if m.ts1 == ts1:
                    rows.append({"tc1_ns": m.tc1, "rtt_ms": (time.monotonic_ns() - ts1) / 1e6,
                                 "tc1_minus_boot_ms": (m.tc1 / 1e6 - last_boot_ms) if last_boot_ms else None})
                    break
    d = [r["tc1_minus_boot_ms"] for r in rows if r["tc1_minus_boot_ms"] is not None]
    return {"asked": n, "answered": len(rows), "its_own_requests_seen": own_requests,
            "rtt_ms_median": float(np.median([r["rtt_ms"] for r in rows])) if rows else None,
            "tc1_minus_last_time_boot_ms_median": float(np.median(d)) if d else None,
            "example": rows[:2]}


def param_or_none(sitl, name: str):
    """The parameter's value, or None when the SITL does not answer (no such parameter)."""
    try:
        return sitl.get_param(name, timeout_s=1.5)
    except SitlError:
        return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frame", default="freestyle")
    args = ap.parse_args()
    res: dict = {}
    with ArduPilotSitl(frame=args.frame, wait_ready=False) as sitl:
        res["first_heartbeat_s"] = round(sitl.elapsed_s(), 2)
        hb = sitl.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1, 5, "hb")
        res["heartbeat"] = {"sysid": hb.get_srcSystem(), "compid": hb.get_srcComponent(),
                            "autopilot": hb.autopilot, "type": hb.type, "base_mode": hb.base_mode,
                            "custom_mode": hb.custom_mode, "system_status": hb.system_status,
                            "mavlink_version": hb.mavlink_version}
        res["params"] = {p: param_or_none(sitl, p) for p in PARAMS}
        res["timesync_before_origin"] = timesync(sitl, 5)
        sitl.set_rate(32, 50)
        lpn = sitl.wait_for(lambda m: m.get_type() in ("LOCAL_POSITION_NED",), 90, "LOCAL_POSITION_NED")
        res["first_local_position_s"] = round(sitl.elapsed_s(), 2)
        res["first_local_position_time_boot_ms"] = lpn.time_boot_ms
        sitl.wait_until(lambda: sitl.prearm_ok, 90, "prearm")
        res["prearm_ok_s"] = round(sitl.elapsed_s(), 2)
        res["first_seen_s"] = {k: round(v, 2) for k, v in sitl.first_seen.items()}
        res["rates"] = [rates(sitl, hz) for hz in (50, 100, 200, 400)]
        res["timesync"] = timesync(sitl)
        res["texts"] = [f"{t:.1f} {s}" for t, s in sitl.texts]
    print(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
