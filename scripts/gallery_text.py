"""docs/gallery.md's text: the table and a caption per figure saying what to look at
(scripts/gallery.py writes the page from it)."""
from __future__ import annotations

CAPTIONS = {
    # name: (plan, simulate, fly)
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
- **simulate** (`mavreg simulate FILE --offset 0.6 0.6 0.6 --plot sim.png`): the design model
  started 1.04 m off the entry (0.85 m across the path). Errors are on a log scale, so the
  metre at the start and the micrometres after convergence are both readable; speed and
  thrust flown against the nominal; the rotor forces applied; and the schedule (arc length
  against time, flown and nominal).
- **fly** (`mavreg fly FILE --lockstep`, the realistic world): the TRUE errors from the
  emulator's ground truth in red (the attitude error is the angle to the plan's nominal
  attitude, which the drag compensation tilts on purpose by up to 15 deg), the controller's
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
             "- **design model**: `mavreg simulate FILE` (1 kHz control, ideal rotors, from the",
             "  nominal entry): maximum transverse and attitude error over the whole maneuver.",
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
            f"| [{r['name']}](#{r['name'].replace('_', '-')}) | {r['yaw_mode']} | "
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
has three times the inertia the plan was designed for. The cause, in the title: {reason}"""
