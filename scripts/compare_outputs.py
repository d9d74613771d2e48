"""Fly the barrel roll with both outputs, rotor forces and body rates + thrust, on the bundled
emulator's realistic world, and print one markdown table: the true path error of the loop
and of the whole maneuver, the outcome, under the world's own link, with extra command delay
and with extra jitter.

    python scripts/compare_outputs.py [--out DIR] [--cases nominal,delay40,...]

Every flight is lockstep (judged by vehicle time; the figures do not depend on the machine),
one at a time. docs/autopilots.md quotes its table.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CASES = {
    "nominal": (),
    "delay +20 ms": ("--uplink-faults=delay_s=0.02",),
    "delay +40 ms": ("--uplink-faults=delay_s=0.04",),
    "delay +60 ms": ("--uplink-faults=delay_s=0.06",),
    "jitter +-5 ms": ("--uplink-faults=jitter_s=0.005", "--downlink-faults=jitter_s=0.005"),
    "jitter +-10 ms": ("--uplink-faults=jitter_s=0.01", "--downlink-faults=jitter_s=0.01"),
}
OUTPUTS = ("rotors", "rates")


def fly(maneuver: str, output: str, extra: tuple[str, ...], out: Path) -> dict:
    cmd = [sys.executable, "-m", "mavreg.cli.main", "fly", maneuver, "--lockstep", "--output", output,
           "--out", str(out), *(f"--emulator-arg={a}" for a in extra)]
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=900)
    try:
        return json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return {"result": "no summary"}


def cell(summary: dict) -> str:
    gt = summary.get("ground_truth") or {}
    loop = (gt.get("segments") or {}).get("loop") or {}
    if not gt:
        return summary.get("result", "?")
    return (f"{summary['result']}: loop {100 * loop.get('max_m', float('nan')):.1f} cm, "
            f"all {100 * gt.get('max_m', float('nan')):.1f} cm")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--maneuver", default="mavreg/params/maneuvers/barrel_roll.yaml")
    p.add_argument("--out", default=None, help="keep the flights here (default: a temporary directory)")
    p.add_argument("--cases", default=",".join(CASES), help="comma-separated subset of: " + ", ".join(CASES))
    args = p.parse_args(argv)
    root = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="mavreg-outputs-"))
    cases = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in cases if c not in CASES]
    if unknown:
        p.error(f"unknown case(s): {', '.join(unknown)}")
    print("| world: realistic + | " + " | ".join(f"output {o}" for o in OUTPUTS) + " |")
    print("|---|" + "---|" * len(OUTPUTS))
    for case in cases:
        row = []
        for output in OUTPUTS:
            slug = case.replace(" ", "_").replace("+-", "pm").replace("+", "p")
            row.append(cell(fly(args.maneuver, output, CASES[case], root / f"{output}-{slug}")))
        print(f"| {case} | " + " | ".join(row) + " |", flush=True)
    print(f"\nflights in {root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
