"""Figures of firmware_sim's realistic world, measured over UDP in lockstep.

The emulator runs as its own process (``--lockstep``, default preset unless flags are
given after ``--``), hovering from an in-flight start; this script is the peer: it
completes samples as the daemon does (ATTITUDE_QUATERNION + LOCAL_POSITION_NED of one
time), answers each with a hover target and sends a TIMESYNC request every 25 samples.
It prints the link statistics, the TIMESYNC delays and the estimate's errors against
the recorded truth of ``t - latency``.

    python benchmarks/fsim_world_figures.py [--duration-s 20] [-- EMULATOR FLAGS]
"""
from __future__ import annotations

import argparse
import json
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.vehicle import G

REPO = Path(__file__).resolve().parents[1]
HOVER = 0.749 * G / 4 / 12.0


def run(duration_s: float, extra: list[str], record: Path) -> dict:
    proc = subprocess.Popen(
        [sys.executable, "-m", "firmware_sim", "--lockstep", "--quiet", "--listen", "udpin:127.0.0.1:0",
         "--start", "z_m=-5", "--duration-s", str(duration_s), "--lockstep-stall-factor", "0",
         "--record", str(record), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    try:
        port = int(proc.stdout.readline().strip().rsplit(":", 1)[1])
        world = proc.stdout.readline().strip()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.connect(("127.0.0.1", port))
        sock.settimeout(0.5)
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
        sock.send(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3).pack(mav))
        att, pos, last, n, sync = set(), set(), -1, 0, []
        t0 = time.perf_counter()
        while True:
            try:
                data = sock.recv(65535)
            except (socket.timeout, ConnectionRefusedError):
                if proc.poll() is not None:
                    break
                continue
            for m in mav.parse_buffer(data) or ():
                kind = m.get_type()
                if kind == "TIMESYNC":
                    sync.append((m.tc1 - m.ts1) / 1e6)
                parts = {"ATTITUDE_QUATERNION": att, "LOCAL_POSITION_NED": pos}.get(kind)
                if parts is None or m.time_boot_ms <= last:
                    continue
                parts.add(m.time_boot_ms)
                t = m.time_boot_ms
                if t in att and t in pos:
                    last, n = t, n + 1
                    att, pos = {x for x in att if x > t}, {x for x in pos if x > t}
                    if n % 25 == 0:
                        sock.send(mavlink2.MAVLink_timesync_message(0, t * 1_000_000).pack(mav))
                    sock.send(mavlink2.MAVLink_set_actuator_control_target_message(
                        0, 0, 1, 1, [HOVER] * 4 + [0.0] * 4).pack(mav))
        wall = time.perf_counter() - t0
        sock.close()
    finally:
        if proc.poll() is None:
            proc.terminate()
        proc.wait(30)
    return {"world": world, "samples": n, "sync_ms": sync, "wall_s": wall}


def main() -> None:
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration-s", type=float, default=20.0)
    args = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    with tempfile.TemporaryDirectory() as tmp:
        rec = Path(tmp) / "r.npz"
        r = run(args.duration_s, extra, rec)
        d = np.load(rec)
        meta = json.loads(str(d["meta_json"]))
    c, world = meta["counters"], meta["world"]
    latency_steps = int(np.floor(world["estimator"]["latency_s"] * meta["physics_hz"] + 0.5))
    rows = np.clip(np.rint(d["estimate_t_s"] * meta["physics_hz"]).astype(int) - latency_steps, 0, None)
    perr = d["estimate_position_ned_m"] - d["position_ned_m"][rows]
    verr = d["estimate_velocity_ned_m_s"] - d["velocity_ned_m_s"][rows]
    werr = d["estimate_rates_rad_s"] - d["body_rates_rad_s"][rows]
    q, qt = d["estimate_quat"], d["quaternion_wxyz"][rows]
    dot = np.abs(np.sum(q * qt, axis=1)).clip(max=1.0)
    angle_deg = np.degrees(2 * np.arccos(dot))
    periods = int(round(args.duration_s * meta["rate_hz"]))
    print(r["world"])
    print(f"{periods} periods in {r['wall_s']:.1f} s wall ({periods / r['wall_s']:.0f} periods/s); "
          f"lockstep timeouts {c['lockstep_timeouts']}; samples completed by the peer {r['samples']}")
    print(f"telemetry: {c['telemetry_sent']} messages sent, {c['telemetry_lost']} lost "
          f"({100 * c['telemetry_lost'] / max(1, c['telemetry_sent'] + c['telemetry_lost']):.2f} %); "
          f"commands: {c['commands_received']} datagrams, {c['commands_lost']} lost "
          f"({100 * c['commands_lost'] / max(1, c['commands_received']):.2f} %)")
    s = np.array(r["sync_ms"])
    if s.size:
        print(f"TIMESYNC tc1 - sample time: n={s.size} mean {s.mean():.2f} ms, min {s.min():.0f}, "
              f"max {s.max():.0f} ms")
    print("estimate errors against the truth of t - latency (RMS per axis, all axes pooled):")
    print(f"  position {1000 * np.sqrt(np.mean(perr ** 2)):.2f} mm, velocity "
          f"{100 * np.sqrt(np.mean(verr ** 2)):.2f} cm/s, attitude angle RMS "
          f"{np.sqrt(np.mean(angle_deg ** 2)) / np.sqrt(3):.3f} deg per axis, body rates "
          f"{np.sqrt(np.mean(werr ** 2)):.4f} rad/s")


if __name__ == "__main__":
    main()
