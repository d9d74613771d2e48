"""``results.json`` and ``results.md`` of a campaign: the tables, the summary, the figures."""
from __future__ import annotations

import json
import math
from pathlib import Path

from .definitions import CONTROLLERS, CONVERGENCE, DISTURBANCE, rotors_label
from .disturbance_metrics import TUBE_M
from .metrics import BACK_ON_PATH_M, CONVERGED_M
from .robustness import ROBUSTNESS

__all__ = ["summarize", "results_dict", "write_results", "markdown"]


def _max(values):
    v = [x for x in values if x is not None]
    return max(v) if v else None


def _summarize_disturbance(ms) -> dict:
    """Per controller: runs, completed, diverged, and the worst of each column."""
    out = {}
    for ctrl in CONTROLLERS:
        mine = [m for m in ms if m["controller"] == ctrl]
        if mine:
            out[ctrl] = {"runs": len(mine), "completed": sum(m["completed"] for m in mine),
                         "diverged": sum(m["diverged"] for m in mine),
                         "max_distance_m": _max([m["max_distance_m"] for m in mine]),
                         "outside_tube_s": _max([m["outside_tube_s"] for m in mine]),
                         "overspeed_m_s": _max([m["overspeed_m_s"] for m in mine]),
                         "min_centre_distance_m": min((m["min_centre_distance_m"] for m in mine
                                                       if m["min_centre_distance_m"] is not None), default=None)}
    return out


def summarize(exp, outcomes) -> dict:
    """The campaign in a few numbers: runs, how many met the criterion, the worst of each column."""
    ms = [o.metrics for o in outcomes if o.metrics is not None]
    if exp.kind == ROBUSTNESS:
        from .robustness_report import summarize as summarize_robustness
        return summarize_robustness(exp, outcomes)
    if exp.kind == DISTURBANCE:
        return {"runs": len(outcomes), "errors": sum(o.metrics is None for o in outcomes),
                "ok": sum(o.ok for o in outcomes), "by_controller": _summarize_disturbance(ms)}
    loop_t = [(m["loop"]["transverse_error_m"] or {}).get("max") for m in ms]
    loop_a = [(m["loop"]["attitude_error_deg"] or {}).get("max") for m in ms]
    out = {"runs": len(outcomes), "errors": sum(o.metrics is None for o in outcomes),
           "ok": sum(o.ok for o in outcomes),
           "loop_max_transverse_error_m": _max(loop_t), "loop_max_attitude_error_deg": _max(loop_a)}
    if exp.kind == CONVERGENCE:
        conv = [m["converged_at_s_m"] for m in ms if m["converged"]]
        out.update(converged=len(conv), converged_at_s_m={"min": min(conv), "max": max(conv)} if conv else None,
                   converge_before_s_m=ms[0]["converge_before_s_m"] if ms else None)
    else:
        out.update(stable=sum(bool(m["stable"]) for m in ms))
    return out


def results_dict(exp, via: str, outcomes, command: str, jobs: int, wall_time_s: float,
                 figures, extra: dict | None = None) -> dict:
    """Everything ``results.json`` holds (JSON-ready)."""
    runs = []
    for o in outcomes:
        if o.metrics is not None:
            runs.append(o.metrics)
        else:
            runs.append({"index": o.spec.index, "label": o.spec.label, "ok": False, "error": o.error})
    if exp.kind == ROBUSTNESS:                     # a run that raised is a ``not flown`` row of its cell
        from .robustness_report import flight_rows
        runs = flight_rows(outcomes)
    return {"experiment": exp.name, "title": exp.title, "kind": exp.kind, "via": via, "seed": exp.seed,
            "jobs": jobs, "command": command, "maneuver": str(exp.maneuver_path),
            "vehicle": str(exp.vehicle_path), "controller": str(exp.controller_path),
            "definitions": (_robustness_definitions() if exp.kind == ROBUSTNESS else
                            {"tube_m": TUBE_M, "documentation": "mavreg/experiments/disturbance_metrics.py"}
                            if exp.kind == DISTURBANCE else
                            {"converged_m": CONVERGED_M, "back_on_path_m": BACK_ON_PATH_M,
                             "documentation": "mavreg/experiments/metrics.py"}),
            "summary": summarize(exp, outcomes), "runs": runs,
            "figures": [Path(f).name for f in figures], "wall_time_s": wall_time_s, **(extra or {})}


def _robustness_definitions() -> dict:
    from .robustness_report import definitions
    return definitions()


def _f(v, scale=1.0, fmt="{:.2f}") -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "—"
    return fmt.format(v * scale)


def _stat(block, key, what, scale=1.0, fmt="{:.2f}"):
    return _f(((block or {}).get(key) or {}).get(what), scale, fmt)


def _table_group1(runs) -> list[str]:
    lines = ["| run | jx, jy, jz (kg m²) | converged | s at convergence (m) | loop max (mm) | loop RMS (mm) "
             "| loop max attitude (deg) | peak thrust (N), \\|γ1\\|, \\|γ2\\|, \\|γ3\\| (N m) after convergence "
             "| the same over the whole maneuver (the start) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for m in runs:
        if "error" in m:
            lines.append(f"| {m['index']} | {m['label']} | error: {m['error']} | | | | | | |")
            continue
        J = "nominal" if m["inertia_kg_m2"] is None else ", ".join(f"{j:.4f}" for j in m["inertia_kg_m2"])
        conv = "yes" if m["converged"] else f"**no** ({m['status']})"
        def peaks(thrust, torques):
            return f"{thrust:.1f}, " + ", ".join(f"{x:.2f}" for x in torques) if torques else "—"
        lines.append(f"| {m['index']} | {J} | {conv} | {_f(m['converged_at_s_m'])} "
                     f"| {_stat(m['loop'], 'transverse_error_m', 'max', 1e3, '{:.3f}')} "
                     f"| {_stat(m['loop'], 'transverse_error_m', 'rms', 1e3, '{:.3f}')} "
                     f"| {_stat(m['loop'], 'attitude_error_deg', 'max', 1, '{:.3f}')} "
                     f"| {peaks(m['converged_peak_thrust_n'], m['converged_peak_torque_n_m'])} "
                     f"| {peaks(m['peak_thrust_n'], m['peak_torque_n_m'])} |")
    return lines


def _table_group2(runs) -> list[str]:
    lines = ["| case | stable | laps | loop max (cm) | loop RMS (cm) | max over the maneuver (cm) "
             "| loop max attitude (deg) | max attitude over the maneuver (deg) | time saturated "
             "| all four rotors asked for the limit or more | loop torque shortfall \\|Δγ1\\|, \\|Δγ2\\|, "
             "\\|Δγ3\\| (N m) | error at the end (cm) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in runs:
        if "error" in m:
            lines.append(f"| {m['label']} | error: {m['error']} | | | | | | | | | | |")
            continue
        st = "yes" if m["stable"] else f"**no** ({m['status']}: {m['reason']})"
        lines.append(f"| {m['label']} | {st} | {m['laps_flown']:.1f} of {m['laps']} "
                     f"| {_stat(m['loop'], 'transverse_error_m', 'max', 100)} "
                     f"| {_stat(m['loop'], 'transverse_error_m', 'rms', 100)} "
                     f"| {_stat(m['overall'], 'transverse_error_m', 'max', 100)} "
                     f"| {_stat(m['loop'], 'attitude_error_deg', 'max', 1, '{:.1f}')} "
                     f"| {_stat(m['overall'], 'attitude_error_deg', 'max', 1, '{:.1f}')} "
                     f"| {100 * m['saturated_share']:.1f} % ({m['saturated_s']:.2f} s) "
                     f"| {m['all_rotors_asked_beyond_limit_s']:.2f} s "
                     f"| {', '.join(f'{x:.2f}' for x in m['loop_torque_shortfall_n_m'] or [])} "
                     f"| {_f(m['final_transverse_error_m'], 100)} |")
    return lines


CONTROLLER_NAMES = {"regulator": "maneuver regulation", "tvlqr": "TVLQR", "se3": "SE(3)"}


def _table_disturbance(runs) -> list[str]:
    lines = ["| case | rotors | controller | outcome | max distance from the path (cm) "
             f"| time outside the {TUBE_M:g} m tube (s) | peak acceleration (m/s²) "
             "| min distance to the loop's centre (m) | overspeed (m/s) | max attitude error (deg) "
             "| late at the end (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in runs:
        if "error" in m:
            lines.append(f"| {m['label']} | | | error: {m['error']} | | | | | | | |")
            continue
        outcome = ("**diverged**" if m["diverged"] else "completed" if m["completed"]
                   else f"**{m['status']}**")
        lines.append(f"| {m['group']} {m['case']} | {rotors_label(m['saturation_n'])} "
                     f"| {CONTROLLER_NAMES.get(m['controller'], m['controller'])} | {outcome} "
                     f"| {_f(m['max_distance_m'], 100, '{:.1f}')} | {_f(m['outside_tube_s'])} "
                     f"| {_f(m['peak_acceleration_m_s2'], 1, '{:.1f}')} | {_f(m['min_centre_distance_m'])} "
                     f"| {_f(m['overspeed_m_s'])} | {_f(m['max_attitude_error_deg'], 1, '{:.1f}')} "
                     f"| {_f(m['late_s'])} |")
    return lines


def _outcome_word(m) -> str:
    if "error" in m:
        return "error"
    if m["diverged"]:
        return "**diverged**"
    return "ok" if m["completed"] else f"**{m['status']}**"


def _pivot_disturbance(runs) -> list[str]:
    """One row per case and rotor limit, each cell the controllers' values in the order of
    :data:`~.definitions.CONTROLLERS` (maneuver regulation / TVLQR / SE(3))."""
    rows: dict = {}
    for m in runs:
        if "error" in m:
            continue
        rows.setdefault((m["group"], m["case"], m["saturation_n"]), {})[m["controller"]] = m
    ctrls = [c for c in CONTROLLERS if any(c in r for r in rows.values())]
    cols = (("max distance from the path (cm)", "max_distance_m", 100, "{:.1f}"),
            (f"time outside the {TUBE_M:g} m tube (s)", "outside_tube_s", 1, "{:.2f}"),
            ("min distance to the loop's centre (m)", "min_centre_distance_m", 1, "{:.2f}"),
            ("overspeed (m/s)", "overspeed_m_s", 1, "{:.2f}"),
            ("peak acceleration (m/s²)", "peak_acceleration_m_s2", 1, "{:.0f}"))
    names = " / ".join(CONTROLLER_NAMES.get(c, c) for c in ctrls)
    lines = [f"Each cell: {names}.", "",
             "| case | rotors | outcome | " + " | ".join(c[0] for c in cols) + " |",
             "|---|---|---|" + "---|" * len(cols)]
    for (group, case, sat), by in rows.items():
        cells = [" / ".join(_outcome_word(by[c]) if c in by else "—" for c in ctrls)]
        for _, key, scale, fmt in cols:
            cells.append(" / ".join(_f(by[c][key], scale, fmt) if c in by else "—" for c in ctrls))
        lines.append(f"| {group} {case} | {rotors_label(sat)} | " + " | ".join(cells) + " |")
    return lines


def _summary_disturbance(sm) -> str:
    parts = []
    for ctrl, c in sm["by_controller"].items():
        parts.append(f"{CONTROLLER_NAMES.get(ctrl, ctrl)}: {c['completed']} of {c['runs']} completed, "
                     f"{c['diverged']} diverged, at most {_f(c['max_distance_m'], 100, '{:.0f}')} cm from the "
                     f"path, {_f(c['overspeed_m_s'])} m/s over the profile, as close as "
                     f"{_f(c['min_centre_distance_m'])} m to the loop's centre (1.5 m on the path)")
    return "**" + "; ".join(parts) + ".**"


def markdown(res: dict) -> str:
    """``results.md`` from a :func:`results_dict`."""
    sm = res["summary"]
    lines = [f"# {res['title']}, via {res['via']}", "",
             f"Command: `{res['command']}` (seed {res['seed']}, {res['jobs']} jobs, "
             f"{res['wall_time_s']:.0f} s wall).", ""]
    if res["kind"] == ROBUSTNESS:
        from .robustness_report import markdown_body
        return "\n".join(lines + markdown_body(res))
    if res["kind"] == DISTURBANCE:
        lines += [_summary_disturbance(sm), "", *_pivot_disturbance(res["runs"]), "", "Every run:"]
        table = _table_disturbance(res["runs"])
    elif res["kind"] == CONVERGENCE:
        rng = sm.get("converged_at_s_m")
        lines.append(f"**Converged before the loop in {sm['converged']} of {sm['runs']} runs** (transverse "
                     f"error below {100 * res['definitions']['converged_m']:g} cm from then until s = "
                     f"{_f(sm.get('converge_before_s_m'), 1, '{:.1f}')} m"
                     + (f"; reached at s = {rng['min']:.2f} to {rng['max']:.2f} m" if rng else "") + "). "
                     f"In the loop, over every run: transverse error at most "
                     f"{_f(sm['loop_max_transverse_error_m'], 1e3, '{:.3f}')} mm, attitude error at most "
                     f"{_f(sm['loop_max_attitude_error_deg'], 1, '{:.3f}')} deg.")
        table = _table_group1(res["runs"])
    else:
        lines.append(f"**Stable in {sm['stable']} of {sm['runs']} cases** (flown to the end of the path, "
                     f"every lap, and back within {100 * res['definitions']['back_on_path_m']:g} cm of it).")
        table = _table_group2(res["runs"])
    if sm["errors"]:
        lines.append(f"{sm['errors']} run(s) could not be flown; see the table.")
    lines += ["", *table, "",
              "Errors are the truth's: each true position projected on the path, each true attitude "
              f"against the nominal one at that arc length ({res['definitions']['documentation']} defines "
              "every column).", ""]
    for f in res["figures"]:
        lines += [f"![{f}]({f})", ""]
    return "\n".join(lines)


def write_results(out_dir: Path, res: dict) -> tuple[Path, Path]:
    """Write ``results.json`` and ``results.md`` into ``out_dir``."""
    out_dir = Path(out_dir)
    j = out_dir / "results.json"
    j.write_text(json.dumps(res, indent=1))
    md = out_dir / "results.md"
    md.write_text(markdown(res))
    return j, md
