"""``mavreg simulate``: fly a maneuver on the design model and report tracking errors."""
from __future__ import annotations

import json
import sys

from .common import add_laps_argument, add_model_arguments, load_maneuver_arg, load_model_params

HELP = "fly a maneuver with the regulator on the design model; tracking errors against s"
DESCRIPTION = """\
Plan the maneuver, start at its nominal entry state (plus --offset), and integrate the
paper's quadrotor model (eqs 6-17, RK4, 1 ms) in closed loop with the s-scheduled LQR
regulator run at --rate-hz with zero-order hold. Rotor forces may carry Gaussian noise and
saturate per rotor; the plant's inertia may differ from the design (--inertia-kg-m2); a gust
(--gust-n, --gust-window) may push the vehicle. The regulator allocates and governs its
speed as the controller file's allocation: and speed_governor: sections say
(docs/governor.md), knowing the --saturation-n limit.
Reports, overall and per named segment: transverse position error (max, RMS), attitude
error (max), rotor command range and time saturated. With --json: stable, completed,
transverse_error_m {max, rms}, attitude_error_deg {max}, segments {...}.

Exit status: 0 stable and completed, 1 diverged or not completed, 2 invalid input.
"""


def add_arguments(p):
    p.add_argument("maneuver", metavar="FILE", help="maneuver YAML (kind: maneuver)")
    p.add_argument("--offset", nargs=3, type=float, default=(0.0, 0.0, 0.0),
                   metavar=("DX", "DY", "DZ"), help="initial position offset, NED metres")
    p.add_argument("--noise-n", type=float, default=0.0, metavar="SD",
                   help="Gaussian noise SD on each rotor force, N (default 0)")
    p.add_argument("--saturation-n", type=float, default=None, metavar="F",
                   help="per-rotor saturation, N, known to the controller's allocation and speed "
                        "governor (default: none)")
    add_laps_argument(p)
    p.add_argument("--seed", type=int, default=None, metavar="N", help="noise seed")
    p.add_argument("--rate-hz", type=float, default=1000.0, help="controller rate (default 1000)")
    p.add_argument("--inertia-kg-m2", nargs=3, type=float, default=None,
                   metavar=("JX", "JY", "JZ"), help="plant inertia (default: the design's)")
    p.add_argument("--gust-n", nargs=3, type=float, default=None, metavar=("FN", "FE", "FD"),
                   help="an external force on the vehicle, NED newtons (with --gust-window)")
    p.add_argument("--gust-window", nargs=2, type=float, default=(0.0, 1.0), metavar=("T0", "T1"),
                   help="when the gust acts, seconds from the start (default 0 1)")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON")
    p.add_argument("--plot", metavar="PNG", default=None,
                   help="save a plot of the path and the errors against s")
    add_model_arguments(p)


def run(args) -> int:
    if args.noise_n < 0:
        raise ValueError(f"--noise-n must be >= 0, got {args.noise_n}")
    if args.saturation_n is not None and args.saturation_n <= 0:
        raise ValueError(f"--saturation-n must be > 0, got {args.saturation_n}")
    if not args.gust_window[0] <= args.gust_window[1]:
        raise ValueError(f"--gust-window must be T0 <= T1, got {args.gust_window}")
    vehicle, controller = load_model_params(args)
    spec = load_maneuver_arg(args)            # the files first: the planner's imports are heavy
    from ..config.regulation import told_rotor_limit
    from ..maneuver.cache import default_cache
    from ..maneuver.plan import plan_cached
    from ..sim.maneuver_run import fly_on_design_model
    plan = plan_cached(spec, vehicle, controller, cache=default_cache())
    print(f"{plan.name}: planned, {plan.length_m:.1f} m in {plan.duration_s:.1f} s; simulating",
          file=sys.stderr, flush=True)
    run_ = fly_on_design_model(plan, offset_m=args.offset, inertia_kg_m2=args.inertia_kg_m2,
                               rotor_noise_sd_n=args.noise_n, saturation_n=args.saturation_n,
                               seed=args.seed, control_rate_hz=args.rate_hz,
                               gust_force_n=args.gust_n, gust_window_s=tuple(args.gust_window),
                               allocation=told_rotor_limit(controller.allocation, args.saturation_n),
                               speed_governor=controller.speed_governor)
    m = run_.metrics
    if args.plot:
        from ..plots import plot_flight
        plot_flight(args.plot, plan, run_.s, run_.w, run_.result.x[:, :3],
                    title=f"{plan.name} on the design model")
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
