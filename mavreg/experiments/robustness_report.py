"""The robustness experiment's summary and ``results.md`` tables (called by :mod:`.report`)."""
from __future__ import annotations

import numpy as np

from .robustness_metrics import (IMPACT_SPEED_M_S, STOPPED_ALTITUDE_M, STOPPED_FORCE_N, STOPPED_MIN_S,
                                 SAFETY_CLASSES)

__all__ = ["flight_rows", "summarize", "definitions", "markdown_body"]


def _stat(values) -> dict | None:
    v = np.asarray([x for x in values if x is not None], dtype=float)
    if v.size == 0:
        return None
    return {"median": float(np.median(v)), "max": float(np.max(v))}


def flight_rows(outcomes) -> list[dict]:
    """Each outcome's metrics; a run that raised counts as ``not flown`` with its error."""
    out = []
    for o in outcomes:
        if o.metrics is not None:
            out.append(o.metrics)
        else:
            sp = o.spec
            out.append({"index": sp.index, "label": sp.label, "cell": sp.cell, "seed": sp.seed,
                        "mismatch_seed": sp.mismatch_seed, "safety": "not flown", "ok": False,
                        "cause": o.error or "error", "result": "not flown"})
    return out


def _cell_summary(ms: list[dict]) -> dict:
    bounds: dict = {}
    for m in ms:
        if m.get("first_bound"):
            bounds[m["first_bound"]] = bounds.get(m["first_bound"], 0) + 1
    lows = [m.get("lowest_altitude_m") for m in ms if m.get("lowest_altitude_m") is not None]
    downs = [m.get("max_touchdown_speed_m_s") for m in ms if m.get("max_touchdown_speed_m_s") is not None]
    return {"flights": len(ms), **{c: sum(m["safety"] == c for m in ms) for c in SAFETY_CLASSES},
            "maneuver_max_error_m": _stat(m.get("maneuver_max_error_m") for m in ms),
            "loop_max_error_m": _stat(m.get("loop_max_error_m") for m in ms),
            "max_attitude_error_deg": _stat(m.get("max_attitude_error_deg") for m in ms),
            "lowest_altitude_m": min(lows) if lows else None,
            "max_touchdown_speed_m_s": max(downs) if downs else None,
            "first_bounds": bounds}


def summarize(exp, outcomes) -> dict:
    """Counts over the campaign (``ok`` = every check passed) and per cell, in matrix order."""
    runs = flight_rows(outcomes)
    by_cell = {}
    for cell in exp.cells:
        mine = [m for m in runs if m.get("cell") == cell.name]
        if mine:
            by_cell[cell.name] = {"group": cell.group, "title": cell.title,
                                  "emulator_args": list(cell.emulator_args), **_cell_summary(mine)}
    return {"runs": len(runs), "errors": sum(o.metrics is None for o in outcomes),
            "ok": sum(m["safety"] == "ok" for m in runs),
            "failed_safe": sum(m["safety"] == "failed, safe" for m in runs),
            "unsafe": sum(m["safety"] == "unsafe" for m in runs),
            "not_flown": sum(m["safety"] == "not flown" for m in runs),
            "flights_per_cell": exp.flights, "by_cell": by_cell}


def definitions() -> dict:
    """The thresholds of :mod:`.robustness_metrics`, for ``results.json``."""
    return {"impact_speed_m_s": IMPACT_SPEED_M_S, "stopped_force_n": STOPPED_FORCE_N,
            "stopped_min_s": STOPPED_MIN_S, "stopped_altitude_m": STOPPED_ALTITUDE_M,
            "documentation": "mavreg/experiments/robustness_metrics.py"}


def _f(v, scale=1.0, fmt="{:.2f}") -> str:
    return "—" if v is None else fmt.format(v * scale)


def _ms(st, scale=100.0, fmt="{:.1f}") -> str:
    return "—" if st is None else f"{_f(st['median'], scale, fmt)} / {_f(st['max'], scale, fmt)}"


def _cell_table(sm) -> list[str]:
    lines = ["| cell | what differs | flights | ok | failed, safe | unsafe | not flown "
             "| maneuver max error, median / max (cm) | loop max error, median / max (cm) "
             "| max attitude error, median / max (deg) | lowest altitude (m) | fastest touchdown (m/s) "
             "| first bounds fired |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, c in sm["by_cell"].items():
        bounds = ", ".join(f"{b} ×{n}" for b, n in sorted(c["first_bounds"].items())) or "—"
        lines.append(f"| {name} | {c['title']} | {c['flights']} | {c['ok']} | {c['failed, safe']} "
                     f"| {'**%d**' % c['unsafe'] if c['unsafe'] else 0} | {c['not flown']} "
                     f"| {_ms(c['maneuver_max_error_m'])} | {_ms(c['loop_max_error_m'])} "
                     f"| {_ms(c['max_attitude_error_deg'], 1.0)} | {_f(c['lowest_altitude_m'])} "
                     f"| {_f(c['max_touchdown_speed_m_s'])} | {bounds} |")
    return lines


def _yes(v) -> str:
    return "—" if v is None else ("**yes**" if v else "no")


def _flight_row(m) -> str:
    seed = f"{m['seed']}" + (f" / {m['mismatch_seed']}" if m.get("mismatch_seed") is not None else "")
    word = {"ok": "ok", "failed, safe": "failed, safe"}.get(m["safety"], f"**{m['safety']}**")
    return (f"| {m['label']} | {seed} | {word} | {_f(m.get('maneuver_max_error_m'), 100, '{:.1f}')} "
            f"| {_f(m.get('loop_max_error_m'), 100, '{:.1f}')} | {_f(m.get('max_attitude_error_deg'), 1, '{:.1f}')} "
            f"| {m.get('first_bound') or '—'} | {_f(m.get('lowest_altitude_m'))} "
            f"| {_f(m.get('max_touchdown_speed_m_s'))} | {_yes(m.get('ground_impact'))} "
            f"| {_yes(m.get('motors_stopped_in_air'))} | {_f(m.get('flight_time_s'), 1, '{:.1f}')} |")


def _flights_table(runs) -> list[str]:
    return ["| flight | seed (/ airframe seed) | outcome | maneuver max error (cm) | loop max error (cm) "
            "| max attitude error (deg) | first bound | lowest altitude (m) | fastest touchdown (m/s) "
            "| ground impact | motors stopped in the air | flight time (s) |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
            *(_flight_row(m) for m in runs)]


def _not_ok(runs) -> list[str]:
    bad = [m for m in runs if not m["ok"]]
    if not bad:
        return ["Every flight ok."]
    lines = ["| flight | outcome | first bound (phase) | action | cause |", "|---|---|---|---|---|"]
    for m in bad:
        bound = f"{m['first_bound']} ({m['bound_phase']})" if m.get("first_bound") else "—"
        lines.append(f"| {m['label']} | {m['safety']} | {bound} | {m.get('action') or '—'} "
                     f"| {(m.get('cause') or '').replace('|', '/')} |")
    return lines


def markdown_body(res: dict) -> list[str]:
    """The lines of ``results.md`` after its command line."""
    sm = res["summary"]
    runs = res["runs"]
    lines = [f"**{sm['runs']} flights ({sm['flights_per_cell']} per cell): {sm['ok']} ok, {sm['failed_safe']} "
             f"failed but safe, {sm['unsafe']} unsafe (motors stopped in the air or a ground impact over "
             f"{IMPACT_SPEED_M_S:g} m/s), {sm['not_flown']} not flown.**", "",
             f"Controller `{res['controller']}` as shipped (its envelope untouched), world `"
             f"{(res.get('sitl') or {}).get('world', 'realistic')}` plus each cell's emulator arguments, lockstep. "
             "Errors are the truth's over the maneuver (the distance from the path); the lowest altitude is "
             "above the take-off point from the end of the take-off to the landing (0: the ground touched); "
             f"{res['definitions']['documentation']} defines every column.", "",
             "## Per cell", "", *_cell_table(sm), "", "## Flights that were not ok", "", *_not_ok(runs), "",
             "## Every flight", "", *_flights_table(runs), ""]
    for f in res["figures"]:
        lines += [f"![{f}]({f})", ""]
    return lines
