"""``mavreg plan``: validate a maneuver, build its nominal and gains, report feasibility."""
from __future__ import annotations

import argparse
import json

from .common import (add_laps_argument, add_model_arguments, input_file, load_maneuver_arg, load_model_params,
                     output_file, plot_file)
from .plan_progress import plan_saying

HELP = "validate a maneuver YAML, check feasibility, build the gain schedule (nothing flies)"
DESCRIPTION = """\
Load a maneuver file, build its path, nominal state and input by differential flatness,
check them against the vehicle (per-rotor thrust in [0, max_rotor_thrust_n], minimum speed,
curvature continuity) and against the flight envelope the daemon holds it to (altitude floor
and geofence of the controller file's envelope: section, for a take-off at the local origin
0, 0, 0), and compute the s-scheduled LQR gains. Prints a summary, or JSON with
--json (feasible, length_m, thrust_n {min, max, at_highest_point}, rotor_force_n {min, max},
torque_nm {max_abs}, segments, margins, ...).

The controller is 'mavreg fly's (default params/controller/realistic.yaml, as fly and serve):
the gains and margins printed are the ones a flight of the same files flies with.

Margins (docs/robustness.md, "Margins"): the delay and common rotor-gain margins of the
hover LQR and of the maneuver regulator (the worst over the plan, and where), on the design
model with the vehicle's rotor lag, the loop broken at the rotor commands. JSON: margins
{rotor_time_constant_s, hover {delay_margin_ms, gain_margin [low, high], ...}, maneuver
{delay_margin_ms, worst_s_m, gain_margin, gain_margin_s_m, nodes, frozen_unstable_s_m}}.

--plot FILE.png draws the nominal: its path in a 3-D, a top (north up, east right) and a side
view at equal scale, with the start, the direction of travel and the numbered segments, and
its speed, collective thrust, rotor forces (against their limit) and body rates against s.
--export FILE.csv|json writes the nominal on the plan's grid: t_s, s_m, NED position (m) and
velocity (m/s), speed, the attitude as a quaternion (w, x, y, z; body FRD to NED) and as roll,
pitch, yaw (deg), body rates (rad/s), collective thrust (N), body torques (N m) and the rotor
forces 1-4 (front, right, back, left; N). CSV: one header line of unit-named columns; JSON:
one object, one array per quantity, units in the keys. Both are written for an infeasible
plan too (its violations are in the summary and the figure's title).

Exit status: 0 feasible, 1 infeasible (the reasons say where in s and by how much) or a
geometry that cannot be flown, 2 invalid file or arguments.
"""


def add_arguments(p):
    p.add_argument("maneuver", metavar="FILE", type=input_file, help="maneuver YAML (kind: maneuver)")
    add_laps_argument(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--plot", metavar="PNG", type=plot_file, default=None,
                   help="save a figure of the nominal (views of the path, speed, thrust, rotor forces)")
    p.add_argument("--export", metavar="FILE", type=_export_file, default=None,
                   help="write the nominal trajectory as FILE.csv or FILE.json (see above)")
    add_model_arguments(p)


def _export_file(text: str) -> str:
    """--export: a .csv or .json file that can be written (checked before planning)."""
    if not text.lower().endswith((".csv", ".json")):
        raise argparse.ArgumentTypeError(f"{text}: the file name must end in .csv or .json")
    return output_file(text)


def run(args) -> int:
    vehicle, controller = load_model_params(args)
    spec = load_maneuver_arg(args)            # the files first: the planner's imports are heavy
    from ..control.controllers.hover import HoverParams
    from ..maneuver.plan_margins import with_margins
    plan = with_margins(plan_saying("plan", spec, vehicle, controller, strict=False),
                        HoverParams.from_controller(controller))
    summary = plan.summary()
    _check_envelope(plan, controller.envelope, summary)
    _write_outputs(args, plan, summary)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(format_summary(summary))
    return 0 if summary["feasible"] else 1


def _write_outputs(args, plan, summary: dict) -> None:
    """--export and --plot (the figure's title carries the verdict)."""
    if args.export is not None:
        from ..planning.nominal_files import write_nominal
        write_nominal(plan, args.export)
    if args.plot is not None:
        from ..plots import plot_plan
        plot_plan(args.plot, plan, violations=summary["violations"])


def _check_envelope(plan, envelope, summary: dict) -> None:
    """The daemon's floor and geofence (the controller file's ``envelope:``), seen from a
    take-off at the local origin: a plan that leaves them would be refused before take-off."""
    from ..daemon.flight.gate import nominal_points, plan_outside_envelope
    origin = (0.0, 0.0, 0.0)
    bad = plan_outside_envelope(nominal_points(plan), origin, envelope)
    summary["envelope"] = {"takeoff_point_ned_m": list(origin), "inside": bad is None,
                           "bound": None if bad is None else bad.bound,
                           "detail": None if bad is None else bad.detail}
    if bad is not None:
        summary["feasible"] = False
        summary["violations"].append(f"{bad.detail}: {bad.value:.2f} {bad.unit} (limit {bad.limit:.2f} "
                                     f"{bad.unit}, take-off at the origin; the envelope: section of the "
                                     "controller file)")


def format_summary(d: dict) -> str:
    th, rf = d["thrust_n"], d["rotor_force_n"]
    lines = [
        f"maneuver {d['name']}: {'FEASIBLE' if d['feasible'] else 'INFEASIBLE'}",
        f"  length {d['length_m']:.2f} m, nominal duration {d['duration_s']:.2f} s, laps {d['laps']}",
        f"  speed {d['speed_m_s']['min']:.2f}..{d['speed_m_s']['max']:.2f} m/s",
        f"  thrust {th['min']:.2f}..{th['max']:.2f} N (at the highest point: "
        f"{th['at_highest_point']:.2f} N, s = {th['highest_point_s_m']:.2f} m)",
        f"  rotor force {rf['min']:.2f}..{rf['max']:.2f} N (limit {rf['limit']:.2f} N)",
        "  torque max |g1 g2 g3| " + " ".join(f"{t:.3f}" for t in d["torque_nm"]["max_abs"]) + " N m",
        f"  gains: {d['gain_schedule']['nodes']} nodes, terminal {d['gain_schedule']['terminal']}",
        "  segments (arc length s, m): " + ", ".join(f"{s['name']} [{s['s_start_m']:.2f}, {s['s_end_m']:.2f})"
                                   for s in d["segments"]),
    ]
    if d.get("from_cache"):
        lines.insert(1, "  served from the plan cache (same files, same code; MAVREG_PLAN_CACHE=off to plan anew)")
    if "margins" in d:
        lines += ["  " + line for line in format_margins(d["margins"])]
    lines += [f"  violation: {v}" for v in d["violations"]]
    return "\n".join(lines)


def _gain(g) -> str:
    lo, hi = g
    return f"x{float(lo):.2f}..x{float(hi):.2f}" if hi != "inf" else f"x{float(lo):.2f}..inf"


def format_margins(m: dict) -> list[str]:
    """One line for the hover, one for the maneuver (units in the text)."""
    h = m["hover"]
    out = [f"margins (rotor lag {m['rotor_time_constant_s'] * 1e3:.0f} ms, loop broken at the rotor "
           f"commands): hover delay {float(h['delay_margin_ms']):.1f} ms, gain {_gain(h['gain_margin'])}"]
    r = m.get("maneuver")
    if r is not None:
        edges = [f"{name} at s = {float(s):.2f} m" for name, s in zip(("low", "high"), r["gain_margin_s_m"])
                 if s != "nan"]
        line = (f"  maneuver delay {float(r['delay_margin_ms']):.1f} ms (worst at s = "
                f"{float(r['worst_s_m']):.2f} m), gain {_gain(r['gain_margin'])}"
                + (f" ({', '.join(edges)})" if edges else "") + f", {r['nodes']} nodes, frozen-time")
        if r["frozen_unstable_s_m"]:
            line += "; not Hurwitz frozen (left out) at s in " + ", ".join(
                f"[{a:.2f}, {b:.2f}]" for a, b in r["frozen_unstable_s_m"]) + " m"
        out.append(line)
    return out
