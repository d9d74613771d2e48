"""The figures of a campaign through one ``serve`` (:mod:`.serve_campaign`): outcomes, unsafe
events, lost results, resources over time, latency; a Markdown table.

Definitions (docs/reliability.md):

- **lost result**: a flight whose upload was accepted and whose record (the daemon's outcome
  of it) never came, or any flight after the daemon died;
- **not flown**: a flight the daemon, still running, did not begin because the vehicle never
  reported itself disarmed after an aborted flight (its own failsafe holds it, and mavreg
  does not take back a vehicle its failsafe flies): an outcome, not a lost result;
- **unsafe event**: a touchdown faster than 1 m/s, the motors stopped in the air (both on the
  emulator's recording when there is one: :mod:`.robustness_metrics`; else the daemon's
  touchdown speed and its ``impact`` outcome), or an arm not asked for (the vehicle armed in a
  flight whose upload was rejected);
- **growth**: of resident memory, descriptors and threads, the largest value from flight
  ``GROWTH_FROM`` on over the value at flight ``GROWTH_FROM``, in percent.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .serve_campaign import KEEP_LOGS
from .robustness_metrics import (IMPACT_SPEED_M_S, altitude_above_takeoff, load_truth, motors_stopped_in_air,
                                 touchdowns)

__all__ = ["judge_truth", "summarize", "markdown", "GROWTH_FROM"]

GROWTH_FROM = 20


def judge_truth(rows: list[dict], record_path) -> None:
    """Add the truth's verdict to each of ``rows``, the flights of one emulator run, from its
    recording over each flight's span of vehicle time (the recording is deleted unless some
    flight was unsafe)."""
    try:
        t, pos, vel, applied, armed, ground, _ = load_truth(record_path)
    except (OSError, KeyError, ValueError) as exc:
        for row in rows:
            row["truth"] = {"error": f"{type(exc).__name__}: {exc}"}
        return
    alt = altitude_above_takeoff(pos)
    unsafe = False
    spans = [(row.get("record") or {}).get("vehicle_span_s") or [None, None] for row in rows]
    for i, (row, span) in enumerate(zip(rows, spans)):
        if span[0] is None or span[1] is None:
            row["truth"] = {"error": "no flight: no span of vehicle time to judge"}
            continue
        # to the next flight's first sample: a flight handed over to the vehicle's failsafe is
        # judged through the failsafe's landing, which comes after the daemon's last sample
        later = [s[0] for s in spans[i + 1:] if s[0] is not None]
        lo, hi = span[0] - 0.5, (later[0] if later else np.inf)
        sel = (t >= lo) & (t <= hi)
        downs = touchdowns(t[sel], vel[sel], ground[sel])
        top = max((v for _, v in downs), default=None)
        stopped = motors_stopped_in_air(t[sel], alt[sel], applied[sel], armed[sel], ground[sel])
        truth = {"max_touchdown_speed_m_s": top, "touchdowns": len(downs),
                 "ground_impact": bool(top is not None and top > IMPACT_SPEED_M_S),
                 "motors_stopped_in_air": stopped is not None,
                 "arm_not_asked": bool(np.any(armed[sel])) and row.get("upload") != "accepted",
                 "recording": str(record_path)}
        row["truth"] = truth
        unsafe |= truth["ground_impact"] or truth["motors_stopped_in_air"] or truth["arm_not_asked"]
    if not unsafe:
        Path(record_path).unlink(missing_ok=True)


def _unsafe(row: dict) -> list[str]:
    truth, rec = row.get("truth"), row.get("record")
    why = []
    if truth and "error" not in truth:
        if truth["ground_impact"]:
            why.append(f"touchdown {truth['max_touchdown_speed_m_s']:.2f} m/s")
        if truth["motors_stopped_in_air"]:
            why.append("motors stopped in the air")
        if truth["arm_not_asked"]:
            why.append("armed, not asked")
    elif rec:
        td = rec.get("touchdown_speed_m_s")
        if td is not None and td > IMPACT_SPEED_M_S:
            why.append(f"touchdown {td:.2f} m/s (daemon)")
        if rec["result"] == "impact":
            why.append("impact")
    return why


def _growth(rows: list[dict], who: str, key: str) -> dict | None:
    """The largest growth over the serves of the campaign (one per shard; flights counted
    within each serve)."""
    worst = None
    for shard in dict.fromkeys(r.get("shard") for r in rows):
        vals = [(r.get("in_shard", r["flight"]), r["resources"][who][key]) for r in rows
                if r.get("shard") == shard and r.get("resources") and who in r["resources"]]
        base = next((v for n, v in vals if n >= GROWTH_FROM), None)
        if not base:
            continue
        later = [v for n, v in vals if n >= GROWTH_FROM]
        g = {"at": base, "max": max(later), "last": later[-1], "growth_pct": 100.0 * (max(later) - base) / base}
        if worst is None or g["growth_pct"] > worst["growth_pct"]:
            worst = g
    return worst


def _latency(rows: list[dict]) -> dict:
    lat = [(r["record"]["latency_ms"].get("median"), r["record"]["latency_ms"].get("p99")) for r in rows
           if r.get("record") and r["record"].get("latency_ms")]
    if not lat:
        return {}
    med = np.array([m for m, _ in lat], dtype=float)
    p99 = np.array([p for _, p in lat], dtype=float)
    k = min(GROWTH_FROM, len(lat))
    return {"median_ms_first": float(np.median(med[:k])), "median_ms_last": float(np.median(med[-k:])),
            "p99_ms_first": float(np.median(p99[:k])), "p99_ms_last": float(np.median(p99[-k:])),
            "p99_ms_max": float(np.max(p99))}


NOT_FLOWN = "not flown: the vehicle stayed armed"


def not_flown(row: dict) -> bool:
    """The daemon, alive after it (its resources read), did not begin this flight: the vehicle
    never reported itself disarmed after the aborted flight before it."""
    return row.get("upload") == "not sent" and row.get("resources") is not None


def summarize(kind: str, result: dict) -> dict:
    rows = result["rows"]
    outcomes: dict[str, int] = {}
    for r in rows:
        key = (r["record"]["result"] if r.get("record") else "upload rejected" if r.get("upload") == "rejected"
               else NOT_FLOWN if not_flown(r) else "lost")
        outcomes[key] = outcomes.get(key, 0) + 1
    lost = [r["flight"] for r in rows
            if r.get("record") is None and r.get("upload") != "rejected" and not not_flown(r)]
    unsafe = {r["flight"]: _unsafe(r) for r in rows if _unsafe(r)}
    hostile = [v for r in rows for v in (r.get("hostile") or {}).values()]
    counters = [r["record"]["counters"] for r in rows if r.get("record")]
    return {
        "campaign": kind, "flights": len(rows), "outcomes": dict(sorted(outcomes.items())),
        "lost_results": lost, "unsafe": unsafe,
        "hostile_uploads": len(hostile), "hostile_not_rejected": sum(v != "rejected" for v in hostile),
        "samples": sum(c["samples"] for c in counters),
        "samples_without_command": sum(c["samples"] - c["actuator_sent"] for c in counters),
        "growth": {f"{who}_{key}": _growth(rows, who, key) for who in ("serve", "worker")
                   for key in ("rss_kb", "fds", "threads")},
        "latency": _latency(rows), "serve_exit": result["serve_exit"], "wall_s": result["wall_s"],
        "log_files_left": None if result.get("log_files") is None else len(result["log_files"]),
        "keep_logs": KEEP_LOGS,
    }


def markdown(sm: dict, command: str) -> str:
    lines = [f"# {sm['campaign']}: {sm['flights']} flights through one `mavreg serve`", "",
             f"`{command}`", "",
             "| outcome | flights |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in sm["outcomes"].items()]
    lines += ["", f"- unsafe events: {len(sm['unsafe'])}" + (f" ({sm['unsafe']})" if sm["unsafe"] else ""),
              f"- lost results: {len(sm['lost_results'])}" + (f" ({sm['lost_results']})" if sm["lost_results"] else ""),
              f"- hostile uploads: {sm['hostile_uploads']}, not rejected: {sm['hostile_not_rejected']}",
              f"- samples: {sm['samples']}, without a command: {sm['samples_without_command']}",
              f"- serve's exit status: {sm['serve_exit']}; wall time {sm['wall_s']:.0f} s",
              f"- log files left by serve (--keep-logs {sm.get('keep_logs')}): {sm.get('log_files_left')}", "",
              f"| resource (from flight {GROWTH_FROM}) | at | max | last | growth |", "|---|---|---|---|---|"]
    for name, g in sm["growth"].items():
        if g is not None:
            lines.append(f"| {name} | {g['at']} | {g['max']} | {g['last']} | {g['growth_pct']:+.1f} % |")
    lat = sm["latency"]
    if lat:
        lines += ["", "| latency, sample to command (median of flights) | first flights | last flights |",
                  "|---|---|---|",
                  f"| median | {lat['median_ms_first']:.3f} ms | {lat['median_ms_last']:.3f} ms |",
                  f"| p99 | {lat['p99_ms_first']:.3f} ms | {lat['p99_ms_last']:.3f} ms |"]
    return "\n".join(lines) + "\n"
