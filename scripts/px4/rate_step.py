#!/usr/bin/env python3
"""Measure a stock PX4's (SIH) roll and pitch rate step as the emulator's --print-rate-response
defines its own: from the SENT step to SIH's true body rate, averaged over repetitions.

    python -m scripts.px4.rate_step [--reps 6] [--step-rad-s 1] [--step-s 0.4]
                                    [--param NAME=VALUE ...] [--instance N] [--json FILE]

PX4 hovers in OFFBOARD on body rates and thrust, levelled by the script's own small stabilizer;
each repetition steps one axis (a doublet: +-step, then -+step for as long) and the figures come
from firmware_sim.rate_response.step_figures (10/50/90 %, overshoot, final value over the last
quarter of the step, first order + delay over 150 ms). harness/px4_rate_step.py says how.
Needs the PX4 SITL (harness/px4_sitl.py says where it is looked for). Real time: under a
minute. Run it alone (no other PX4 flight on the machine); times are on PX4's clock.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness.px4_rate_step import measure_px4_rate_step
from harness.sitl_link import parse_param_items

AXES = {"roll": 0, "pitch": 1}


def describe(r) -> str:
    """One step's figures as the emulator's --print-rate-response prints them."""
    return (f"10/50/90 % at {1e3 * r.t10_s:.1f}/{1e3 * r.t50_s:.1f}/{1e3 * r.t90_s:.1f} ms, overshoot "
            f"{100 * r.overshoot:.1f} %, final {r.final:.3f}; first order + delay: tau {1e3 * r.tau_s:.1f} ms, "
            f"delay {1e3 * r.delay_s:.1f} ms")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--axes", default="roll,pitch", help="comma-separated: roll, pitch (default %(default)s)")
    p.add_argument("--reps", type=int, default=6, help="steps per axis, signs alternating (default %(default)s)")
    p.add_argument("--step-rad-s", type=float, default=1.0, help="step size, rad/s (default %(default)s)")
    p.add_argument("--step-s", type=float, default=0.4,
                   help="how long the step is held (the window measured; default %(default)s)")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="a PX4 parameter set before the flight (repeatable)")
    p.add_argument("--instance", type=int, default=None, metavar="N",
                   help="PX4's instance, 0-9 (default: the first free one)")
    p.add_argument("--json", default=None, metavar="FILE", help="also write the figures and the mean responses here")
    args = p.parse_args(argv)
    try:
        axes = tuple(AXES[a.strip()] for a in args.axes.split(","))
    except KeyError as exc:
        p.error(f"--axes: unknown axis {exc}")
    if not 1 <= args.reps <= 20 or not 0.05 <= args.step_s <= 0.4 or not 0.1 <= args.step_rad_s <= 3.0:
        p.error("want --reps 1..20, --step-s 0.05..0.4, --step-rad-s 0.1..3")
    if args.instance is not None and not 0 <= args.instance <= 9:
        p.error(f"--instance {args.instance}: want 0 to 9")
    res = measure_px4_rate_step(axes, args.reps, args.step_rad_s, args.step_s,
                                params=parse_param_items(p, args.param), instance=args.instance)
    print("PX4 parameters read: " + ", ".join(f"{k} {v:g}" for k, v in res["params"].items() if v is not None))
    print(f"samples: truth {res['truth_hz']:.0f} Hz, ATTITUDE {res['attitude_hz']:.0f} Hz; PX4's clock ran at "
          f"{res['sim_speed']:.3f} x the wall clock over the steps")
    names = {v: k for k, v in AXES.items()}
    for axis in axes:
        for key, what in (("truth", "SIH truth (HIL_STATE_QUATERNION)"), ("attitude", "ATTITUDE (filtered gyro)")):
            print(f"px4 rate step {names[axis]} ({args.step_rad_s:g} rad/s, {res['steps'][axis]} steps, from the "
                  f"send to {what}): {describe(res[key][axis])}")
    if args.json:
        doc = {"params": res["params"], "truth_hz": res["truth_hz"], "attitude_hz": res["attitude_hz"],
               "sim_speed": res["sim_speed"], "steps": {names[a]: n for a, n in res["steps"].items()}}
        for key in ("truth", "attitude"):
            doc[key] = {names[a]: {"t10_s": r.t10_s, "t50_s": r.t50_s, "t90_s": r.t90_s, "overshoot": r.overshoot,
                                   "final": r.final, "tau_s": r.tau_s, "delay_s": r.delay_s,
                                   "t_s": r.t_s.tolist(), "rate_rad_s": r.rate_rad_s.tolist()}
                        for a, r in res[key].items()}
        Path(args.json).write_text(json.dumps(doc, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
