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

from ...sim.metrics import rotor_jitter_n, tracking_metrics
from ...sim.truth import quats_to_matrices, true_errors
from ..flight.supervisor import PHASE_CODES, Phase

__all__ = ["controller_metrics", "ground_truth_errors", "format_summary", "plot_flight", "TABLE_LEGEND"]


def _maneuver_rows(ctrl: dict) -> np.ndarray:
    return ctrl["phase"] == PHASE_CODES[Phase.MANEUVER]


def controller_metrics(ctrl: dict, plan, max_rotor_thrust_n: float) -> dict:
    """tracking_metrics over the maneuver's control steps of a control-log dict."""
    m = _maneuver_rows(ctrl)
    if not np.any(m):
        return {}
    t = ctrl["t_s"][m]
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    rotors = ctrl["rotor_cmd_n"][m].astype(float)
    if not dt > 0.0:     # one step (the link lost as the maneuver began): no time to count saturation in
        out = tracking_metrics(ctrl["s_m"][m].astype(float), ctrl["w"][m].astype(float), plan.segments,
                               rotor_forces_n=rotors)
        out["rotor_jitter_n"] = None
        return out
    out = tracking_metrics(ctrl["s_m"][m].astype(float), ctrl["w"][m].astype(float), plan.segments,
                           rotor_forces_n=rotors, max_rotor_thrust_n=max_rotor_thrust_n, dt_s=dt)
    out["rotor_jitter_n"] = rotor_jitter_n(rotors, 1.0 / dt)
    return out


def ground_truth_errors(record: dict, plan, t_begin_s: float, t_end_s: float) -> dict:
    """True transverse (and, with ``quaternion_wxyz`` and ``velocity_ned_m_s`` recorded,
    attitude and speed) errors of the recorded states within [t_begin, t_end] of vehicle time (:func:`mavreg.sim.truth.true_errors`)."""
    t = record["t_s"]
    sel = np.flatnonzero((t >= t_begin_s) & (t <= t_end_s))
    quats = record.get("quaternion_wxyz")
    vel = record.get("velocity_ned_m_s")
    return true_errors(plan, record["position_ned_m"][sel],
                       None if quats is None else quats_to_matrices(quats[sel]),
                       None if vel is None else vel[sel])


def _f(v, scale=1.0, fmt="{:8.4f}") -> str:
    return "     n/a" if v is None or (isinstance(v, float) and math.isnan(v)) else fmt.format(v * scale)


TABLE_LEGEND = ("columns: e_t = transverse error, the distance from the path (the controller's "
                "estimate; 'true' from the emulator's ground truth), mm; att = attitude error angle, deg "
                "('true': against the plan's drag-free nominal attitude, so it includes the tilt flown on "
                "purpose against drag and wind); peak rotor = largest rotor force command, N; "
                "sat = time with a rotor at its limit, s")
"""One line under ``fly``'s table (and in ``mavreg fly --help``): what each column is."""

EVENT_KINDS = ("phase", "touchdown", "command_refused", "gap", "recover", "recovered", "motors_stopped",
               "hand_over", "refused", "hard_landing", "vehicle_id", "dialect", "disarming")
"""The events listed under ``fly``'s table (all of them are in summary.json)."""


def format_summary(summary: dict) -> str:
    """Human-readable per-segment table of a summary dict (see ``mavreg fly``)."""
    lines = [f"flight {summary['result']}: {summary['maneuver']} "
             f"({summary['length_m']:.2f} m) in {summary['flight_time_s']:.1f} s"]
    if summary.get("reason"):
        lines.append(f"cause: {summary['reason']}")
    peaks = (summary.get("status") or {}).get("envelope_peaks") or {}
    if peaks:
        top = sorted(peaks.items(), key=lambda kv: -kv[1]["ratio"])[:4]
        lines.append("closest to the envelope (share of the bound): " + ", ".join(
            f"{name} {100 * p['ratio']:.0f} %" for name, p in top))
    est = (summary.get("status") or {}).get("disturbance")
    if est:
        f_n, f_e = est["force_ned_n"][0], est["force_ned_n"][1]
        lines.append(f"airframe as estimated: drag c_xy {est['drag_n_s_per_m'][0]:.3f} N s/m, c_z "
                     f"{est['drag_n_s_per_m'][1]:.3f} N s/m; steady force north {f_n:+.2f} N, east "
                     f"{f_e:+.2f} N; thrust scale {est['thrust_scale']:.3f} "
                     f"({est['updates']} samples, {est['rejected']} refused)")
        tb = est.get("torque_bias")
        if tb:
            t0, t1 = tb["constant_n_m"], tb["per_thrust_m"]
            lines.append(f"torque bias as estimated: t1 {t1[0] * 1e3:+.1f} {t1[1] * 1e3:+.1f} {t1[2] * 1e3:+.1f} "
                         f"mm (N m per N of thrust), t0 {t0[0]:+.3f} {t0[1]:+.3f} {t0[2]:+.3f} N m "
                         f"({tb['updates']} samples, {tb['rejected']} refused)")
        lag = est.get("rotor_lag")
        if lag:
            lines.append(f"rotor time constant as estimated: {lag['time_constant_s'] * 1e3:.1f} ms "
                         f"(+/- {lag['sd_s'] * 1e3:.1f}; the vehicle file's {lag['file_s'] * 1e3:.1f} ms; "
                         f"{lag['updates']} samples, {lag['rejected']} refused)")
    lines.extend(_link_line(summary.get("status") or {}))
    cm = summary.get("controller_metrics") or {}
    gt = summary.get("ground_truth") or {}
    lines.append(f"{'segment':<16}{'max e_t mm':>11}{'rms e_t mm':>11}{'true max mm':>12}"
                 f"{'max att deg':>12}{'true att deg':>13}{'peak rotor N':>13}{'sat s':>7}")

    def row(name, blk, g):
        te = blk.get("transverse_error_m") or {}
        ae = blk.get("attitude_error_deg") or {}
        rc = blk.get("rotor_command_n") or {}
        return (f"{name:<16}{_f(te.get('max'), 1e3, '{:11.1f}')}{_f(te.get('rms'), 1e3, '{:11.1f}')}"
                f"{_f((g or {}).get('max_m'), 1e3, '{:12.1f}')}{_f(ae.get('max'), 1, '{:12.2f}')}"
                f"{_f((g or {}).get('max_deg'), 1, '{:13.2f}')}"
                f"{_f(rc.get('max'), 1, '{:13.2f}')}{_f(blk.get('saturated_s'), 1, '{:7.3f}')}")

    for name, blk in (cm.get("segments") or {}).items():
        lines.append(row(name, blk, (gt.get("segments") or {}).get(name)))
    if cm:
        lines.append(row("all", cm, gt))
        lines.append(TABLE_LEGEND)
        if cm.get("rotor_jitter_n") is not None:
            lines.append(f"rotor command jitter (SD above 20 Hz, worst rotor): {cm['rotor_jitter_n']:.3f} N")
    shown = [ev for ev in summary.get("events", []) if ev["kind"] in EVENT_KINDS]
    if shown:
        lines.append("events (t: the vehicle's time; daemon: since the daemon started):")
    for ev in shown:
        t = f"t={ev['time_s']:8.3f} s" if ev.get("time_s") is not None else " " * 12
        d = f"daemon {ev['daemon_time_s']:8.3f} s  " if ev.get("daemon_time_s") is not None else ""
        lines.append(f"  {t}  {d}{ev['phase']:<9} {ev['detail']}")
    return "\n".join(lines)


def _link_line(status: dict) -> list:
    """One line on signing and what the link dropped, when signing is on or something was dropped."""
    link, sg = status.get("link") or {}, status.get("signing")
    names = ("unsigned", "bad_signature", "replayed", "setup_signing", "foreign_system", "foreign_address")
    dropped = ", ".join(f"{k.replace('_', ' ')} {link[k]}" for k in names if link.get(k))
    if sg is None and not dropped:
        return []
    head = f"link: signing on, {sg['accepted']} signed frames accepted" if sg else "link: signing off"
    return [f"{head}; dropped: {dropped or 'none'}"]


def plot_flight(path, ctrl: dict, plan, record: dict | None, summary: dict | None = None,
                heading: str = "") -> None:
    """The flight figure (:func:`mavreg.plots.plot_fly`): true errors from the recording, the
    outcome and any failure from the summary, ``heading`` its first title line."""
    from ...plots import plot_fly
    plot_fly(path, plan, ctrl, record, summary, heading)
