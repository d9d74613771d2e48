"""N real-time flights of the barrel roll on the bundled emulator's realistic world.

    python benchmarks/realworld_flights.py [--flights 10] [--world realistic] [--seed0 0]

Each flight is exactly what a user runs (``mavreg fly params/maneuvers/barrel_roll.yaml``,
real time, default controller), with the emulator seeded ``seed0 + i`` (its estimator, link
and rotor-noise draws). Prints one row per flight, judged on the emulator's ground truth:
result, the loop's maximum true transverse and attitude errors, rotor-command jitter (SD
above 20 Hz, worst rotor, over the maneuver), the commands' range, the TIMESYNC delay,
and the sample-to-command latency. Figures: docs/robustness.md.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
from mavreg.config.paths import PARAMS_DIR  # noqa: E402


def one_flight(out: Path, world: str, seed: int) -> dict:
    from mavreg.daemon.jobs.ctrllog import load_control_log
    from mavreg.sim.metrics import rotor_jitter_n
    cmd = [sys.executable, "-m", "mavreg.cli.main", "fly", str(PARAMS_DIR / "maneuvers/barrel_roll.yaml"),
           "--out", str(out), "--world", world, f"--emulator-arg=--seed={seed}"]
    code = subprocess.run(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                          timeout=600).returncode
    try:
        s = json.loads((out / "summary.json").read_text())
    except (OSError, ValueError):
        return {"code": code, "result": "no summary"}
    row = {"code": code, "result": s["result"], "reason": s.get("reason", "")}
    loop = (((s.get("ground_truth") or {}).get("segments") or {}).get("loop")) or {}
    row["loop_cm"] = None if loop.get("max_m") is None else 100 * loop["max_m"]
    row["loop_deg"] = loop.get("max_deg")
    ctrl = load_control_log(out / "control.npz")
    m = ctrl["phase"] == 4
    if m.any():
        r = ctrl["rotor_cmd_n"][m].astype(float)
        row["jitter_n"] = rotor_jitter_n(r, 500.0)
        row["rotor_min_n"], row["rotor_max_n"] = float(r.min()), float(r.max())
    d = (s.get("status") or {}).get("link_delay_ms") or {}
    row["delay_ms"] = d.get("sample_to_actuation")
    row["latency_p99_ms"] = (s.get("latency_ms") or {}).get("p99")
    return row


def _fmt(v, f="{:.2f}"):
    return "n/a" if v is None else f.format(v)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--flights", type=int, default=10)
    p.add_argument("--world", choices=("realistic", "ideal"), default="realistic")
    p.add_argument("--seed0", type=int, default=0)
    a = p.parse_args(argv)
    print(f"{'#':>3} {'result':>7} {'loop cm':>8} {'loop deg':>9} {'jitter N':>9} {'rotors N':>12} "
          f"{'delay ms':>9} {'lat p99 ms':>11}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(a.flights):
            r = one_flight(Path(tmp) / f"f{i}", a.world, a.seed0 + i)
            rows.append(r)
            rng = (f"{r['rotor_min_n']:.2f}..{r['rotor_max_n']:.2f}" if "rotor_min_n" in r else "n/a")
            print(f"{i:>3} {r['result']:>7} {_fmt(r.get('loop_cm')):>8} {_fmt(r.get('loop_deg')):>9} "
                  f"{_fmt(r.get('jitter_n'), '{:.3f}'):>9} {rng:>12} {_fmt(r.get('delay_ms'), '{:.1f}'):>9} "
                  f"{_fmt(r.get('latency_p99_ms')):>11}" + ("" if r["result"] == "ok" else f"  {r.get('reason', '')}"),
                  flush=True)
    ok = sum(r["result"] == "ok" for r in rows)
    loops = [r["loop_cm"] for r in rows if r.get("loop_cm") is not None]
    print(f"{ok} of {len(rows)} flights ok; loop max over all flights "
          f"{max(loops) if loops else float('nan'):.2f} cm")
    return 0 if ok == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
