"""``python -m fuzz``: a long seeded fuzz run of the receive paths; prints frames per target and findings.

Example (three minutes per target, seed 1)::

    python -m fuzz --seconds 180 --seed 1

Each target gets datagrams of every kind in turn (random bytes, damaged frames, CRC-valid
frames of any message, of the messages it acts on, and of those with extreme values),
drawn from ``random.Random(seed)``; a finding names the input in hex, so it can be fed
again. Exit status 1 if anything was found.
"""
from __future__ import annotations

import argparse
import collections
import random
import sys
import time

from .frames import DAEMON_ACTS_ON, KINDS, VEHICLE_ACTS_ON, draw_frames
from .targets import DaemonTarget, VehicleTarget

TARGETS = {
    "daemon": (lambda: DaemonTarget("fast"), DAEMON_ACTS_ON, (1, 1)),
    "daemon-reference": (lambda: DaemonTarget("reference"), DAEMON_ACTS_ON, (1, 1)),
    "vehicle": (VehicleTarget, VEHICLE_ACTS_ON, (1, 191)),
}


def run_target(name: str, seconds: float, max_inputs: int | None, seed: int) -> dict:
    """Fuzz one target; returns its counts and findings (at most 5 examples per kind)."""
    make, acts_on, ids = TARGETS[name]
    target = make()
    rng = random.Random(f"fuzz:{seed}:{name}")
    frames = collections.Counter()
    inputs = 0
    findings: dict = {}
    counts = collections.Counter()
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end and (max_inputs is None or inputs < max_inputs):
        for kind in KINDS:
            parts = draw_frames(rng, kind, acts_on, *ids)
            frames[kind] += len(parts)
            inputs += 1
            for f in target.feed(b"".join(parts)):
                key = f.split(" (input")[0].split(":")[0] + ": " + f.split(": ", 1)[1].split(" (input")[0][:80]
                counts[key] += 1
                findings.setdefault(key, f)
    if hasattr(target, "close"):
        target.close()
    return {"inputs": inputs, "frames": dict(frames), "counts": dict(counts), "examples": findings}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m fuzz", description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=60.0, help="per target (default %(default)s)")
    p.add_argument("--inputs", type=int, default=None, help="stop a target after this many datagrams")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target", choices=("all",) + tuple(TARGETS), default="all")
    args = p.parse_args(argv)
    names = tuple(TARGETS) if args.target == "all" else (args.target,)
    found = 0
    for name in names:
        t0 = time.monotonic()
        r = run_target(name, args.seconds, args.inputs, args.seed)
        total = sum(r["frames"].values())
        per_kind = " ".join(f"{k}={v}" for k, v in r["frames"].items())
        print(f"{name}: {r['inputs']} datagrams, {total} frames ({per_kind}) in {time.monotonic() - t0:.0f} s; "
              f"findings: {sum(r['counts'].values())}", flush=True)
        for key, n in sorted(r["counts"].items(), key=lambda kv: -kv[1]):
            print(f"  {n} x {r['examples'][key][:300]}", flush=True)
        found += sum(r["counts"].values())
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
