"""Flight summary and plot: per-segment tracking metrics, ground truth when recorded.

From the daemon's controller log (what the controller saw) it computes, per segment,
the max/RMS transverse error, the max attitude error, the peak rotor commands and the
time saturated (:func:`mavreg.sim.metrics.tracking_metrics`). From an emulator
recording (``firmware_sim --record``) it computes the *true* transverse error: each
recorded position during the maneuver projected on the plan's path.
"""
from __future__ import annotations

import math

import numpy as np

from ..geometry.projection import Projector
from ..sim.metrics import tracking_metrics
from .supervisor import PHASE_CODES, Phase

__all__ = ["controller_metrics", "ground_truth_errors", "format_summary", "plot_flight"]


def _maneuver_rows(ctrl: dict) -> np.ndarray:
    return ctrl["phase"] == PHASE_CODES[Phase.MANEUVER]


def controller_metrics(ctrl: dict, plan, max_rotor_thrust_n: float) -> dict:
    """tracking_metrics over the maneuver's control steps of a control-log dict."""
    m = _maneuver_rows(ctrl)
    if not np.any(m):
        return {}
    t = ctrl["t_s"][m]
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    return tracking_metrics(ctrl["s_m"][m].astype(float), ctrl["w"][m].astype(float), plan.segments,
                            rotor_forces_n=ctrl["rotor_cmd_n"][m].astype(float),
                            max_rotor_thrust_n=max_rotor_thrust_n, dt_s=dt)


def ground_truth_errors(record: dict, plan, t_begin_s: float, t_end_s: float) -> dict:
    """True transverse error of the recorded positions within [t_begin, t_end] (vehicle time).

    Returns ``{"max_m", "rms_m", "samples", "segments": {name: {"max_m", "rms_m"}}}``;
    samples whose projection falls outside (0, length) are left out.
    """
    t = record["t_s"]
    sel = np.flatnonzero((t >= t_begin_s) & (t <= t_end_s))
    proj = Projector(plan.path)
    s_all, e_all = [], []
    first = True
    for i in sel:
        p = record["position_ned_m"][i]
        pr = proj.reset(p, 0.0) if first else proj.update(p)
        first = False
        if 0.0 < pr.s < plan.length_m:
            s_all.append(pr.s)
            e_all.append(pr.distance_m)
    s_arr, e_arr = np.array(s_all), np.array(e_all)
    out = {"samples": int(e_arr.size), "segments": {}}
    out.update(_stats(e_arr))
    for name, a, b in plan.segments:
        mask = (s_arr >= a) & (s_arr < b)
        out["segments"][name] = _stats(e_arr[mask])
    return out


def _stats(e: np.ndarray) -> dict:
    if e.size == 0:
        return {"max_m": None, "rms_m": None}
    return {"max_m": float(e.max()), "rms_m": float(np.sqrt(np.mean(e * e)))}


def _f(v, scale=1.0, fmt="{:8.4f}") -> str:
    return "     n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v * scale)


def format_summary(summary: dict) -> str:
    """Human-readable per-segment table of a summary dict (see ``mavreg fly``)."""
    lines = [f"flight {summary['result']}: {summary['maneuver']} "
             f"({summary['length_m']:.2f} m) in {summary['flight_time_s']:.1f} s"]
    if summary.get("reason"):
        lines.append(f"cause: {summary['reason']}")
    peaks = (summary.get("status") or {}).get("envelope_peaks") or {}
    if peaks:
        top = sorted(peaks.items(), key=lambda kv: -kv[1]["ratio"])[:4]
        lines.append("closest to the envelope: " + ", ".join(
            f"{name} {100 * p['ratio']:.0f} %" for name, p in top))
    cm = summary.get("controller_metrics") or {}
    gt = summary.get("ground_truth") or {}
    lines.append(f"{'segment':<16}{'max e_t cm':>11}{'rms e_t cm':>11}{'true max cm':>12}"
                 f"{'max att deg':>12}{'peak rotor N':>13}{'sat s':>7}")

    def row(name, blk, g):
        te = blk.get("transverse_error_m") or {}
        ae = blk.get("attitude_error_deg") or {}
        rc = blk.get("rotor_command_n") or {}
        return (f"{name:<16}{_f(te.get('max'), 100, '{:11.2f}')}{_f(te.get('rms'), 100, '{:11.2f}')}"
                f"{_f((g or {}).get('max_m'), 100, '{:12.2f}')}{_f(ae.get('max'), 1, '{:12.2f}')}"
                f"{_f(rc.get('max'), 1, '{:13.2f}')}{_f(blk.get('saturated_s'), 1, '{:7.3f}')}")

    for name, blk in (cm.get("segments") or {}).items():
        lines.append(row(name, blk, (gt.get("segments") or {}).get(name)))
    if cm:
        lines.append(row("all", cm, gt))
    for ev in summary.get("events", []):
        if ev["kind"] in ("phase", "touchdown", "command_refused", "gap", "recover", "motors_stopped",
                          "hand_over", "refused", "hard_landing"):
            lines.append(f"  t={ev['time_s'] if ev['time_s'] is not None else float('nan'):8.3f} s "
                         f"{ev['phase']:<9} {ev['detail']}")
    return "\n".join(lines)


def plot_flight(path, ctrl: dict, plan, record: dict | None) -> None:
    """The flight plot (:func:`mavreg.plots.plot_flight`) from a control log and a recording."""
    from ..plots import plot_flight as plot
    m = _maneuver_rows(ctrl)
    truth = record["position_ned_m"][::5] if record is not None else None
    plot(path, plan, ctrl["s_m"][m], ctrl["w"][m], ctrl["x"][:, :3], truth)
