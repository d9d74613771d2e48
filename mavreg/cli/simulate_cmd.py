"""``mavreg simulate``: fly a maneuver on the design model and report tracking errors."""
from __future__ import annotations

import json
import sys

from ..errors import UsageError
from .common import (add_deprecated_alias, add_entry_offset_argument, add_laps_argument, add_model_arguments,
                     finite_float, input_file, load_maneuver_arg, load_model_params, nonneg_float, nonneg_int,
                     plot_file, positive_float)
from .plan_progress import plan_saying

PHYSICS_STEP_S = 1e-3
"""The design model's RK4 step (mavreg.sim.maneuver_run): --control-rate-hz divides its rate."""

HELP = "fly a maneuver with the regulator on the design model; tracking errors against s"
DESCRIPTION = """\
Plan the maneuver, start at its nominal entry state (plus --entry-offset), and integrate
the paper's quadrotor model (eqs 6-17, RK4, 1 ms) in closed loop with the s-scheduled LQR
regulator run at --control-rate-hz with zero-order hold. Rotor forces may carry Gaussian
noise (--rotor-noise-sd-n) and saturate per rotor (--rotor-saturation-n); the plant's
inertia may differ from the design (--inertia-kg-m2); a gust (--gust-n, --gust-window-s) may
push the vehicle. The gains are those of the controller file (default: mavreg fly's,
params/controller/realistic.yaml, designed for the vehicle's rotor lag; the paper's design is
--controller params/controller/paper_lqr.yaml). The regulator allocates and governs its speed as the controller file's
allocation: and speed_governor: sections say (docs/governor.md), knowing the
--rotor-saturation-n limit.
Reports, overall and per named segment: transverse position error (max, RMS; mm in the
text), attitude error (max, deg), rotor command range and time saturated. With --json, in
the units of the keys: stable, completed, transverse_error_m {max, rms}, attitude_error_deg
{max}, segments {NAME: {..., s_start_m, s_end_m, samples}}.

Exit status: 0 stable and completed, 1 diverged or not completed (or the maneuver cannot
be flown), 2 invalid input (options, files; --plot is checked before the simulation).
"""


def control_rate_hz(text: str) -> float:
    """--control-rate-hz: a positive rate whose period is a whole number of physics steps."""
    import argparse
    rate = positive_float(text)
    steps = round(1.0 / (rate * PHYSICS_STEP_S))
    if steps < 1 or abs(steps * PHYSICS_STEP_S * rate - 1.0) > 1e-9:
        raise argparse.ArgumentTypeError(f"expected 1000 Hz divided by a whole number (1000, 500, 250, "
                                         f"...; the model steps every {PHYSICS_STEP_S * 1e3:g} ms), got {text!r}")
    return rate


def add_arguments(p):
    p.add_argument("maneuver", metavar="FILE", type=input_file, help="maneuver YAML (kind: maneuver)")
    add_deprecated_alias(p, "--offset", add_entry_offset_argument(
        p, "start this far (NED, m) from the maneuver's entry, with the entry's velocity, attitude "
        "and rates"))
    add_deprecated_alias(p, "--noise-n", p.add_argument(
        "--rotor-noise-sd-n", type=nonneg_float, default=0.0, metavar="SD",
        help="Gaussian noise SD on each rotor force, N (default 0)"))
    add_deprecated_alias(p, "--saturation-n", p.add_argument(
        "--rotor-saturation-n", type=positive_float, default=None, metavar="F",
        help="the rotors give at most F N; here the controller's allocation and speed governor "
        "are told the limit (default: none)"))
    add_laps_argument(p)
    p.add_argument("--seed", type=nonneg_int, default=None, metavar="N", help="noise seed")
    add_deprecated_alias(p, "--rate-hz", p.add_argument(
        "--control-rate-hz", type=control_rate_hz, default=1000.0, metavar="HZ",
        help="the regulator's rate, 1000 Hz divided by a whole number (default %(default)s)"))
    p.add_argument("--inertia-kg-m2", nargs=3, type=positive_float, default=None,
                   metavar=("JX", "JY", "JZ"), help="plant inertia (default: the design's)")
    p.add_argument("--gust-n", nargs=3, type=finite_float, default=None, metavar=("FN", "FE", "FD"),
                   help="an external force on the vehicle, NED newtons (with --gust-window-s)")
    add_deprecated_alias(p, "--gust-window", p.add_argument(
        "--gust-window-s", nargs=2, type=finite_float, default=(0.0, 1.0), metavar=("T0", "T1"),
        help="when the gust acts, seconds from the start (default 0 1)"))
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.add_argument("--plot", metavar="PNG", type=plot_file, default=None,
                   help="save a figure: the path flown (3-D, top and side views, north up), the "
                   "errors against s (log scale), speed, thrust, rotor forces and schedule")
    add_model_arguments(p)


def run(args) -> int:
    if not args.gust_window_s[0] <= args.gust_window_s[1]:
        raise UsageError(f"--gust-window-s must be T0 <= T1, got {' '.join(f'{t:g}' for t in args.gust_window_s)}")
    vehicle, controller = load_model_params(args)
    spec = load_maneuver_arg(args)            # the files first: the planner's imports are heavy
    from ..api import simulate           # the library's simulate is this command's run
    plan = plan_saying("simulate", spec, vehicle, controller)
    print(f"{plan.name}: planned, {plan.length_m:.1f} m in {plan.duration_s:.1f} s; simulating",
          file=sys.stderr, flush=True)
    run_ = simulate(plan, controller, entry_offset=args.entry_offset, rotor_noise_sd_n=args.rotor_noise_sd_n,
                    rotor_saturation_n=args.rotor_saturation_n, seed=args.seed,
                    control_rate_hz=args.control_rate_hz, inertia_kg_m2=args.inertia_kg_m2,
                    gust_n=args.gust_n, gust_window_s=tuple(args.gust_window_s))
    m = run_.metrics
    if args.plot:
        from ..plots import plot_simulation
        plot_simulation(args.plot, plan, run_, args.control_rate_hz, _heading(plan, args))
    if args.json:
        print(json.dumps(m, indent=2))
    else:
        print(f"{plan.name}: {m['status']} ({m['reason']})")
        print(f"  transverse error max {m['transverse_error_m']['max'] * 1e3:.3g} mm, "
              f"rms {m['transverse_error_m']['rms'] * 1e3:.3g} mm; attitude error max "
              f"{m['attitude_error_deg']['max']:.3g} deg")
        for name, seg in m["segments"].items():
            if seg["samples"]:
                print(f"  {name:>14}: transverse max {seg['transverse_error_m']['max'] * 1e3:9.3g} mm, "
                      f"rms {seg['transverse_error_m']['rms'] * 1e3:9.3g} mm; attitude max "
                      f"{seg['attitude_error_deg']['max']:9.3g} deg")
    return 0 if m["stable"] and m["completed"] else 1


def _heading(plan, args) -> str:
    """The figure's first title line: the maneuver and what was changed from the nominal."""
    extras = [f"offset {' '.join(f'{v:g}' for v in args.entry_offset)} m NED" if any(args.entry_offset) else "",
              f"rotor noise {args.rotor_noise_sd_n:g} N" if args.rotor_noise_sd_n else "",
              f"rotors saturate at {args.rotor_saturation_n:g} N" if args.rotor_saturation_n else "",
              f"gust {' '.join(f'{v:g}' for v in args.gust_n)} N NED" if args.gust_n else "",
              f"control {args.control_rate_hz:g} Hz"]
    return f"{plan.name} on the design model ({', '.join(e for e in extras if e)})"
