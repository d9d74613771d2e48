"""Lockstep control periods per second of firmware_sim with a trivial controller.

The emulator runs as its own process (``--lockstep``, 1 kHz physics, in flight at hover);
this script is the controller: a plain pymavlink codec on a UDP socket that answers
each period's LOCAL_POSITION_NED with a hover SET_ACTUATOR_CONTROL_TARGET.

    python benchmarks/bench_firmware_sim.py [--periods N]
"""
from __future__ import annotations

import argparse
import socket
import subprocess
import sys
import time
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2

REPO = Path(__file__).resolve().parents[1]
HOVER = 0.749 * 9.81 / 4 / 12.0


def bench(rate_hz: int, periods: int, physics_hz: int = 1000) -> tuple[float, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "firmware_sim", "--lockstep", "--quiet", "--listen", "udpin:127.0.0.1:0",
         "--rate-hz", str(rate_hz), "--physics-hz", str(physics_hz), "--start", "z_m=-50"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO)
    try:
        port = int(proc.stdout.readline().strip().rsplit(":", 1)[1])
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        sock.connect(("127.0.0.1", port))
        sock.settimeout(2.0)
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
        target = mavlink2.MAVLink_set_actuator_control_target_message
        sock.send(mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3).pack(mav))
        done = 0
        t0 = None
        warmup = min(500, periods // 10)
        while done < periods + warmup:
            for m in mav.parse_buffer(sock.recv(65535)) or ():
                if m.get_type() == "LOCAL_POSITION_NED":
                    sock.send(target(int(time.monotonic() * 1e6), 0, 1, 1,
                                     [HOVER, HOVER, HOVER, HOVER, 0, 0, 0, 0]).pack(mav))
                    done += 1
                    if done == warmup:
                        t0 = time.perf_counter()
        rate = periods / (time.perf_counter() - t0)
        sock.close()
    finally:
        proc.terminate()
        proc.wait(10)
    status = proc.stdout.read().strip().splitlines()
    return rate, status[-1] if status else ""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--periods", type=int, default=10000)
    args = ap.parse_args()
    for rate_hz in (500, 1000):
        rate, _ = bench(rate_hz, args.periods)
        print(f"lockstep, physics 1000 Hz, control {rate_hz:4d} Hz: {rate:7.0f} periods/s "
              f"({rate / rate_hz:5.1f}x real time, {1e6 / rate:6.1f} us per period)")


if __name__ == "__main__":
    main()
