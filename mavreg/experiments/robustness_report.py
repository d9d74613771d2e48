"""The robustness experiment's summary and ``results.md`` tables (called by :mod:`.report`)."""
from __future__ import annotations

import numpy as np

from .robustness_metrics import (IMPACT_SPEED_M_S, STOPPED_ALTITUDE_M, STOPPED_FORCE_N, STOPPED_MIN_S,
                                 SAFETY_CLASSES, SIM_CLASSES)

__all__ = ["flight_rows", "summarize", "definitions", "markdown_body", "classes"]


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


def classes(via: str) -> tuple[str, ...]:
    """The outcome classes of a campaign flown ``via`` sim or sitl."""
    return SIM_CLASSES if via == "sim" else SAFETY_CLASSES


def _cell_summary(ms: list[dict], via: str) -> dict:
    bounds: dict = {}
    for m in ms:
        if m.get("first_bound"):
            bounds[m["first_bound"]] = bounds.get(m["first_bound"], 0) + 1
    lows = [m.get("lowest_altitude_m") for m in ms if m.get("lowest_altitude_m") is not None]
    downs = [m.get("max_touchdown_speed_m_s") for m in ms if m.get("max_touchdown_speed_m_s") is not None]
    return {"flights": len(ms), **{c: sum(m["safety"] == c for m in ms) for c in classes(via)},
            "maneuver_max_error_m": _stat(m.get("maneuver_max_error_m") for m in ms),
            "loop_max_error_m": _stat(m.get("loop_max_error_m") for m in ms),
            "max_attitude_error_deg": _stat(m.get("max_attitude_error_deg") for m in ms),
            "overspeed_m_s": _stat(m.get("overspeed_m_s") for m in ms),
            "lowest_altitude_m": min(lows) if lows else None,
            "max_touchdown_speed_m_s": max(downs) if downs else None,
            "first_bounds": bounds}


def summarize(exp, outcomes) -> dict:
    """Counts over the campaign (``ok`` = every check passed) and per cell, in matrix order."""
    runs = flight_rows(outcomes)
    via = getattr(exp, "via", "sitl")
    by_cell = {}
    for cell in exp.cells:
        mine = [m for m in runs if m.get("cell") == cell.name]
        if mine:
            by_cell[cell.name] = {"group": cell.group, "title": cell.title,
                                  "emulator_args": list(cell.emulator_args), **_cell_summary(mine, via)}
    counts = {c.replace(", ", "_").replace(" ", "_"): sum(m["safety"] == c for m in runs) for c in classes(via)}
    return {"runs": len(runs), "errors": sum(o.metrics is None for o in outcomes), **counts,
            "flights_per_cell": exp.flights, "by_cell": by_cell,
            "skipped_cells": [{"cell": c, "why": why} for c, why in getattr(exp, "skipped", ())]}


def definitions() -> dict:
    """The thresholds of :mod:`.robustness_metrics`, for ``results.json``."""
    return {"impact_speed_m_s": IMPACT_SPEED_M_S, "stopped_force_n": STOPPED_FORCE_N,
            "stopped_min_s": STOPPED_MIN_S, "stopped_altitude_m": STOPPED_ALTITUDE_M,
            "documentation": "mavreg/experiments/robustness_metrics.py"}


def _f(v, scale=1.0, fmt="{:.2f}") -> str:
    return "—" if v is None else fmt.format(v * scale)


def _ms(st, scale=100.0, fmt="{:.1f}") -> str:
    return "—" if st is None else f"{_f(st['median'], scale, fmt)} / {_f(st['max'], scale, fmt)}"


def _cell_table(sm, via: str = "sitl") -> list[str]:
    cls = classes(via)
    lines = ["| cell | what differs | flights | " + " | ".join(cls) + " "
             "| maneuver max error, median / max (cm) | loop max error, median / max (cm) "
             "| max attitude error, median / max (deg) | overspeed, median / max (m/s) | lowest altitude (m) "
             "| fastest touchdown (m/s) | first bounds fired |",
             "|---" * (10 + len(cls)) + "|"]
    for name, c in sm["by_cell"].items():
        bounds = ", ".join(f"{b} ×{n}" for b, n in sorted(c["first_bounds"].items())) or "—"
        counts = " | ".join(f"**{c[k]}**" if c[k] and k in ("unsafe", "failed") else str(c[k]) for k in cls)
        lines.append(f"| {name} | {c['title']} | {c['flights']} | {counts} "
                     f"| {_ms(c['maneuver_max_error_m'])} | {_ms(c['loop_max_error_m'])} "
                     f"| {_ms(c['max_attitude_error_deg'], 1.0)} | {_ms(c['overspeed_m_s'], 1.0, '{:.2f}')} "
                     f"| {_f(c['lowest_altitude_m'])} "
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


def _head(res: dict) -> list[str]:
    sm = res["summary"]
    if res.get("via") == "sim":
        skipped = [f"{k['cell']} ({k['why']})" for k in sm.get("skipped_cells", [])]
        return [f"**{sm['runs']} flights ({sm['flights_per_cell']} per cell) on the design model: {sm['ok']} "
                f"reached the path's end, {sm['failed']} did not (diverged or timed out), {sm['not_flown']} "
                "not flown.**", "",
                f"Controller `{res['controller']}` (its gains, allocation, speed governor, prediction and "
                "disturbance observer; no safety layer), the maneuver alone from its entry to its end on the "
                f"design model in a version of the realistic world: {(res.get('sim') or {}).get('world', '')} "
                "This judges the controller; via sitl judges the product (take-off to landing, the safety "
                "layer), so the lowest altitude, touchdowns and motor stops are via sitl only (—). Errors are "
                f"the truth's; {res['definitions']['documentation']} defines every column.", "",
                "Not flown via sim: " + ("; ".join(skipped) if skipped else "none of the chosen cells") + ".", ""]
    return [f"**{sm['runs']} flights ({sm['flights_per_cell']} per cell): {sm['ok']} ok, {sm['failed_safe']} "
            f"failed but safe, {sm['unsafe']} unsafe (motors stopped in the air or a ground impact over "
            f"{IMPACT_SPEED_M_S:g} m/s), {sm['not_flown']} not flown.**", "",
            f"Controller `{res['controller']}` as shipped (its envelope untouched), world `"
            f"{(res.get('sitl') or {}).get('world', 'realistic')}` plus each cell's emulator arguments, lockstep. "
            "Errors are the truth's over the maneuver (the distance from the path); the lowest altitude is "
            "above the take-off point from the end of the take-off to the landing (0: the ground touched); "
            f"{res['definitions']['documentation']} defines every column.", ""]


def markdown_body(res: dict) -> list[str]:
    """The lines of ``results.md`` after its command line."""
    sm = res["summary"]
    runs = res["runs"]
    lines = [*_head(res),
             "## Per cell", "", *_cell_table(sm, res.get("via", "sitl")), "", "## Flights that were not ok", "",
             *_not_ok(runs), "",
             "## Every flight", "", *_flights_table(runs), ""]
    for f in res["figures"]:
        lines += [f"![{f}]({f})", ""]
    return lines
