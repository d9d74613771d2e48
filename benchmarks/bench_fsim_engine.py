"""CPU time per control period of firmware_sim's engine, in-process, by world preset.

One period = ``begin_period`` (commands due, autopilot update, telemetry packed and sent
to a sink socket on loopback), one decoded hover SET_ACTUATOR_CONTROL_TARGET received,
``step`` (the physics). No peer process, so the figure is the emulator's own cost and,
being process CPU time (best of 5 runs), holds up on a loaded machine. Hovering from an
in-flight start, default vehicle.

    python benchmarks/bench_fsim_engine.py [--periods N] [-- EXTRA FIRMWARE_SIM FLAGS]
"""
from __future__ import annotations

import argparse
import socket
import sys
import time

from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim import cli


def cpu_us_per_period(rate_hz: int, flags: list[str], periods: int) -> float:
    args = ["--listen", "udpin:127.0.0.1:0", "--quiet", "--start", "z_m=-50", "--rate-hz", str(rate_hz), *flags]
    engine, _ = cli.build_engine(cli.build_parser().parse_args(args))
    sink = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sink.bind(("127.0.0.1", 0))
    engine.link.peers.append(sink.getsockname())
    hover = engine.sim.params.vehicle.mass_kg * 9.81 / 4 / engine.sim.params.vehicle.max_rotor_thrust_n
    packed = mavlink2.MAVLink_set_actuator_control_target_message(
        0, 0, 1, 1, [hover] * 4 + [0.0] * 4).pack(mavlink2.MAVLink(None, 1, 191))
    target = mavlink2.MAVLink(None).parse_buffer(packed)[0]

    def period():
        engine.begin_period()
        engine.receive([target])
        engine.step()
    try:
        for _ in range(500):
            period()
        runs = []
        for _ in range(5):
            t0 = time.process_time()
            for _ in range(periods):
                period()
            runs.append((time.process_time() - t0) / periods * 1e6)
    finally:
        engine.link.close()
        sink.close()
    return min(runs)


def main() -> None:
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--periods", type=int, default=4000)
    args = ap.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    for rate_hz in (500, 1000):
        for preset in ("ideal", "realistic"):
            us = cpu_us_per_period(rate_hz, ["--preset", preset, *extra], args.periods)
            print(f"engine, physics 1000 Hz, control {rate_hz:4d} Hz, --preset {preset:9s}: "
                  f"{us:6.1f} us CPU per period")


if __name__ == "__main__":
    main()
