"""Lockstep control periods per second of firmware_sim with a trivial controller.

A thin wrapper kept for the old command: the measurement is
:func:`benchmarks.sitl.trivial_lockstep` (part of ``python -m benchmarks``; alone:
``python -m benchmarks.sitl``), here on the fast I/O path and on the reference one
(``MAVREG_IO=reference``), default realistic world and ideal world.

    python benchmarks/bench_firmware_sim.py [--periods N]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.sitl import trivial_lockstep  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--periods", type=int, default=10000)
    args = ap.parse_args()
    for preset in ("realistic", "ideal"):
        for io in ("reference", "fast"):
            r = trivial_lockstep(io, args.periods, preset)
            print(f"lockstep, --world {preset:9s}, 500 Hz control, 1 kHz physics, {io:9s} I/O: "
                  f"{r['periods_per_s']:7.0f} periods/s ({r['periods_per_s'] / 500:5.1f}x real time)")


if __name__ == "__main__":
    main()
