"""CPU time per control period of firmware_sim's engine, in-process, by world preset.

A thin wrapper kept for the old command: the measurement is
:func:`benchmarks.sitl.engine_cpu_us` (part of ``python -m benchmarks``), on the fast
path and on the reference one (pymavlink codec, one datagram per message,
``RigidBody.rk4_step_reference``).

    python benchmarks/bench_fsim_engine.py [--periods N]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from benchmarks.sitl import engine_cpu_us  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--periods", type=int, default=4000)
    args = ap.parse_args()
    for preset in ("ideal", "realistic"):
        for io in ("reference", "fast"):
            print(f"engine, 500 Hz control, 1 kHz physics, --world {preset:9s}, {io:9s}: "
                  f"{engine_cpu_us(io, preset, args.periods):6.1f} us CPU per period")


if __name__ == "__main__":
    main()
