"""docs/gallery.md's text: the table and a caption per figure saying what to look at
(scripts/gallery.py writes the page from it)."""
from __future__ import annotations

_SIM = ("the transverse error falls from the 85 cm start to about a micrometre within the run-up "
        "(segment 1) and stays there{extra}; a red triangle on the top edge of the thrust or rotor "
        "panel marks the first instants' peak, beyond the scale (its value is in the legend; the design "
        "model's rotors do not saturate); the schedule panel compares the arc length flown with the "
        "nominal's, against time.")
_FLY = ("the red TRUE transverse error (ground truth) against the controller's own (blue){extra}; the "
        "true attitude error is 5 to 30 deg wherever the speed is high: the angle to the plan's nominal, "
        "which the drag compensation tilts on purpose, while the controller's own error stays near 1 deg; "
        "the true speed against the nominal (at 7 and 8 m/s it runs about 5 % under it); the commanded "
        "thrust follows "
        "the nominal with the realistic world's noise on it; the phase panel shows the take-off, hold, "
        "run-in, maneuver, hold and landing.")

CAPTIONS = {
    "barrel_roll": (
        "the side view from the south shows the 3 m circle in the east-down plane, flown westwards "
        "(the arrows point left); the top view is a line, as it should be. The thrust peaks near 37 "
        "and 39 N entering and leaving the circle (25 N over its top) and falls under the weight only "
        "on the climbing run-out; all four "
        "rotor forces peak near 10 N, under the 12 N limit; the roll rate p carries the 360 deg roll "
        "(up to 400 deg/s at the top).",
        _SIM.format(extra=" (the small rises in segments 2-4 are the loop)"),
        _FLY.format(extra=": a few centimetres along the run-up and the circle")),
    "forward_loop": (
        "the side view from the east shows the vertical 4 m circle at the 18 m mark, the top view only "
        "a line north; the pitch rate q carries the loop (above 300 deg/s); thrust peaks twice near "
        "25 N (entry and exit of the loop, 6 N per rotor) with the 11 N minimum at the inverted top.",
        _SIM.format(extra=""),
        _FLY.format(extra=" through the pitch through +-90 deg")),
    "split_s": (
        "the side view: level at 8 m going north, a half loop down, level at 3 m coming back south "
        "under the start (in the top view both legs lie on one line, arrows both ways). The thrust "
        "dips to 3.5 N as it pushes over at 0.65 g, then peaks near 12 N pulling out; the rotor forces "
        "stay between 0.5 and 3 N.",
        _SIM.format(extra=""),
        _FLY.format(extra=": 1 to 3 cm; in the push-over (s = 17 m) the commanded rotor "
                          "forces fall nearly to zero and come back")),
    "immelmann": (
        "the side view: a half loop up from 2 m to 8 m ending north-to-south; the speed slows from 7 to "
        "4.5 m/s in the climb so that the thrust at the top is under the weight (about 3 N) and never "
        "zero; the yaw rate r turns the nose round on the slow run-out.",
        _SIM.format(extra=""),
        _FLY.format(extra=": 1 to 3 cm, the commanded thrust 5 N over the top")),
    "figure_eight": (
        "the top view: the right circle east of the line, then the left one west of it, as a map "
        "shows them; the side view is flat at 3 m; the thrust steps to 8.9 N in both turns (35 deg of "
        "bank) and the yaw rate r changes sign between them.",
        _SIM.format(extra=""),
        _FLY.format(extra=": 1 to 3 cm through both circles; at s = 31 m, where the "
                          "bank reverses between them, the commanded rotor forces swap sides")),
    "climbing_helix": (
        "the top view: one circle (the three turns lie on it) east of the run-up line; the side view: "
        "the climb of 1.5 m a turn as a zigzag; thrust near 9.3-10 N in the helix, the yaw and pitch "
        "rates steady at about 70 and 60 deg/s. The climb is not uniform along a turn (it rises mostly "
        "on the eastern half): entered from the level run-up, the helix's axis leans about 4 deg from "
        "the vertical.",
        _SIM.format(extra=" (the rise at s = 66-75 m is the exit blend)"),
        _FLY.format(extra=": 1 to 3 cm over the three turns; the whole-flight panel shows "
                          "the uneven climb as steps")),
    "slalom": (
        "the top view: the first swerve after the run-up goes right (east, positive x), to the gate "
        "2 m east, then left, right, left; the run-out ends about 3 m east of the line. The thrust "
        "peaks at each gate (up to 9.9 N), the rotor forces swing between 1 and 3 N.",
        _SIM.format(extra=""),
        _FLY.format(extra=": 1 to 3 cm through the gates; the take-off lasts 33 s because the "
                          "hold point is 30 m south of the take-off point")),
}
"""What to look at in each maneuver's figures (plan, simulate from 0.6 m off, fly realistic)."""

HOW_TO_READ = """\
How to read the figures. Every figure has the same top row: a 3-D view (altitude up), a top
view (north up, east right: a map) and a side view looking along the horizontal axis the path
spans least (its title says from where), all at equal scale. The dashed line is the nominal
path; the green dot is the start, the black square the end, the arrow heads the direction of
travel; the purple numbers mark where each segment starts (the key on the right names them;
the same numbers stand above the panels against arc length s, whose grey lines are the segment
boundaries).

- **plan** (`mavreg plan FILE --plot plan.png`): the nominal's speed, collective thrust (the
  dotted line is the weight), rotor forces against their limit (red bands where a rotor would
  exceed it or pull) and body rates, against s.
- **simulate** (`mavreg simulate FILE --controller params/controller/design.yaml --entry-offset
  0.6 0.6 0.6 --plot sim.png`): the design model
  started 1.04 m off the entry (0.85 m across the path). Errors are on a log scale, so the
  metre at the start and the micrometres after convergence are both readable; speed and
  thrust flown against the nominal; the rotor forces applied; and the schedule (arc length
  against time, flown and nominal).
- **fly** (`mavreg fly FILE --lockstep`, the realistic world): the TRUE errors from the
  emulator's ground truth in red (the attitude error is the angle to the plan's nominal
  attitude, which the drag compensation tilts on purpose: 5 to 30 deg here), the controller's
  own errors in blue; the commanded thrust and rotor forces; and the whole flight by phase.
  A failed flight says why in its red title and carries a red cross where it failed (and a
  red line at that s)."""


def _cell(r: dict | None) -> str:
    if r is None:
        return "not flown"
    if not r["ok"]:
        return f"failed: {r['reason']}"
    c = r["controller"]
    return (f"{r['transverse_cm']:.2f} cm, {c['attitude_error_deg']['max']:.1f} deg, "
            f"{c['rotor_command_n']['max']:.1f} N")


def _figure(name: str, kind: str, caption: str) -> list[str]:
    return [f"![{name} {kind}](gallery/{name}_{kind}.png)", "", f"*{kind}:* {caption}", ""]


def markdown(rows, sitl: bool, failed: dict | None) -> str:
    lines = ["# Maneuver gallery", "",
             "Every file of `params/maneuvers/`, planned with `params/controller/design.yaml` (the",
             "paper's weights on the SO(3) attitude error) on the MK-Quadro (12 N rotors), and flown.",
             "Made by `python scripts/gallery.py --sitl`.", "",
             "- **design model**: `mavreg simulate FILE --controller params/controller/design.yaml`",
             "  (1 kHz control, ideal rotors, from the nominal entry): maximum transverse and attitude",
             "  error over the whole maneuver.",
             "- **SITL ideal**: `mavreg fly FILE --lockstep --world ideal --controller",
             "  params/controller/design.yaml`: the daemon against firmware_sim, true state, no delay.",
             "- **SITL realistic**: `mavreg fly FILE --lockstep` (the defaults: the realistic world's",
             "  20 ms rotor lag, link delay and loss, estimator noise and drag; realistic.yaml).",
             "  SITL columns: the true (ground-truth) maximum transverse error over the maneuver",
             "  (run-up to run-out), the regulator's maximum attitude error (against the nominal it",
             "  flies: the drag compensation turns it by up to 15 deg in the realistic world) and",
             "  the peak rotor command.", "",
             "| maneuver | yaw mode | length, time | max pitch | peak rotor (plan) | design model | "
             "SITL ideal | SITL realistic |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        d = r["design"]
        lines.append(
            f"| [{r['name']}](#{r['name']}) | {r['yaw_mode']} | "
            f"{r['length_m']:.0f} m, {r['duration_s']:.0f} s | {r['max_pitch_deg']:.0f} deg | "
            f"{d['nominal_peak_rotor_n']:.1f} N | {d['transverse_mm']:.3f} mm, {d['attitude_deg']:.4f} deg | "
            f"{_cell(r.get('sitl_ideal')) if sitl else 'not flown'} | "
            f"{_cell(r.get('sitl_realistic')) if sitl else 'not flown'} |")
    lines += ["", HOW_TO_READ]
    for r in rows:
        plan_c, sim_c, fly_c = CAPTIONS.get(r["name"], ("", "", ""))
        lines += ["", f"## {r['name']}", "", r["description"] or "", ""]
        lines += _figure(r["name"], "plan", plan_c)
        lines += _figure(r["name"], "simulate", sim_c)
        if sitl:
            lines += _figure(r["name"], "fly", fly_c)
    if failed is not None:
        lines += ["", "## A failed flight", "", FAILED_CAPTION.format(reason=failed.get("reason", "")), "",
                  "![failed barrel roll](gallery/failed_barrel_roll_fly.png)", ""]
    return "\n".join(lines).rstrip() + "\n"


FAILED_CAPTION = """\
`mavreg fly params/maneuvers/barrel_roll.yaml --lockstep --world ideal --controller
params/controller/paper_lqr.yaml --emulator-arg=--inertia-scale=3`: the emulator's airframe
has three times the inertia the plan was designed for. What to look at: the title, in red,
gives the cause; the red cross in the views is where the vehicle was when the bound fired, past
the circle on the run-out; the red line in the panels is its arc length. The true errors grow
from the end of the circle (segment 4), where the rotor commands oscillate and the commanded
collective thrust falls below zero (rotors cannot pull); the whole-flight panel shows the
recovery (orange) climbing away from the path before the landing. The cause: {reason}"""
