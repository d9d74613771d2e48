"""Daemon latency and CPU at a 500 Hz real-time loop.

Starts firmware_sim in real time (500 Hz telemetry, no lockstep) and ``mavreg fly`` on the
barrel roll as two processes. While it flies, samples the daemon process's CPU time from
/proc every second; at the end prints

- latency from a complete state sample (the datagram that completes it) to the
  SET_ACTUATOR_CONTROL_TARGET sent, median and 99th percentile, overall and in the maneuver;
- the daemon's CPU use (percent of one core), average and per phase;
- the loop's rate: commands sent per state sample received.

Usage: python benchmarks/bench_daemon.py [--out DIR]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests" / "sitl"))
from sitl_helpers import BARREL, mavreg, start_emulator  # noqa: E402

_TICK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / _TICK


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=None, help="output directory (default: a temporary one)")
    args = ap.parse_args()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bench_daemon_"))
    emu, url = start_emulator(out / "groundtruth.npz")
    fly = mavreg("fly", str(BARREL), "--vehicle", url, "--out", str(out / "flight"), "--timeout-s", "300")
    cpu = []   # (wall, cpu seconds, phase)
    phase = "start"
    try:
        while fly.p.poll() is None:
            for ln in fly.lines[-50:]:
                if "] phase" in ln:
                    phase = ln.split("[", 1)[1].split("]", 1)[0]
            try:
                cpu.append((time.monotonic(), cpu_s(fly.p.pid), phase))
            except (FileNotFoundError, ProcessLookupError):
                break
            time.sleep(1.0)
        code = fly.wait(60)
    finally:
        fly.stop()
        emu.stop()
    summary = json.loads((out / "flight" / "summary.json").read_text())
    lat = summary["latency_ms"]
    st = summary["status"]
    per_phase: dict[str, list[float]] = {}
    for (w0, c0, _), (w1, c1, ph) in zip(cpu, cpu[1:]):
        per_phase.setdefault(ph, []).append(100.0 * (c1 - c0) / (w1 - w0))
    flying = [v for ph, vs in per_phase.items() if ph not in ("start", "preflight") for v in vs]
    print(f"mavreg daemon benchmark: barrel roll, firmware_sim real time at 500 Hz, {os.cpu_count()} CPUs")
    print(f"flight: {summary['result']} (exit {code}), {summary['flight_time_s']:.1f} s of flight, "
          f"wall {summary['wall_time_s']:.1f} s")
    print(f"latency sample->command: median {lat['median']:.3f} ms, p99 {lat['p99']:.3f} ms "
          f"({lat['samples']} commands)")
    if "maneuver_latency_ms" in summary and summary["maneuver_latency_ms"]:
        ml = summary["maneuver_latency_ms"]
        print(f"  in the maneuver (regulator): median {ml['median']:.3f} ms, p99 {ml['p99']:.3f} ms")
    c = st["counters"]
    print(f"loop rate: {c['actuator_sent']} commands for {c['samples']} complete samples "
          f"({100.0 * c['actuator_sent'] / max(c['samples'], 1):.1f}%)")
    if flying:
        print(f"daemon CPU while flying: mean {sum(flying) / len(flying):.1f}% of one core, "
              f"max {max(flying):.1f}%")
    for ph, vs in per_phase.items():
        print(f"  {ph:<10} {sum(vs) / len(vs):5.1f}% ({len(vs)} s)")
    print(f"outputs: {out}")
    return 0 if code == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
