"""What a flight figure draws, gathered from what mavreg already computed.

:func:`from_simulation` reads a :class:`~mavreg.sim.maneuver_run.ManeuverRun` (the design
model: the controller sees the true state, so its errors are the true ones);
:func:`from_fly` reads ``mavreg fly``'s control log, the emulator's ground-truth recording
and the summary (outcome, failure). Errors come from :func:`mavreg.sim.metrics.error_series`
and :func:`mavreg.sim.truth.true_error_series`; nothing here integrates or linearizes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sim.metrics import error_series

__all__ = ["FlightData", "Series", "from_simulation", "from_fly"]

MAX_TRUTH_SAMPLES = 3000
"""The ground truth is projected on the path at most this many times (a figure needs no more)."""


@dataclass(frozen=True)
class Series:
    """Samples against arc length (NaN-free, in flight order)."""

    s_m: np.ndarray
    values: np.ndarray
    label: str


@dataclass(frozen=True)
class FlightData:
    """Everything :func:`mavreg.plots.figures.flight_figure` draws."""

    heading: str
    """First title line: the maneuver and where it was flown."""
    outcome: str
    """Second title line: 'completed' or FAILED and why."""
    ok: bool
    maneuver_ned: np.ndarray
    """Positions flown during the maneuver (truth where there is one)."""
    maneuver_label: str
    transverse_m: list[Series]
    attitude_deg: list[Series]
    speed_m_s: Series | None
    thrust_n: Series | None
    rotors_n: Series | None
    other_ned: np.ndarray | None = None
    """Positions outside the maneuver (take-off, hold, landing, recovery)."""
    progress: tuple[np.ndarray, np.ndarray] | None = None
    """(t_s, s_m) flown, for the schedule panel (simulate)."""
    timeline: dict | None = None
    """{t_s, altitude_m, label, phases [(name, t0, t1)]} of the whole flight (fly)."""
    failure: dict | None = None
    """{text, t_s, s_m, ned}: where and why it failed."""
    no_maneuver: str = "no maneuver samples"
    """What the panels against s say when there is nothing to draw."""


def from_simulation(plan, run, control_rate_hz: float, heading: str) -> FlightData:
    """The design-model flight of ``mavreg simulate`` (its state is the truth)."""
    res = run.result
    dt = float(res.t[1] - res.t[0]) if res.t.size > 1 else 1e-3
    steps = max(1, int(round(1.0 / (control_rate_hz * dt))))
    n = len(run.s)
    idx = np.minimum(np.arange(n) * steps, len(res.t) - 1)
    trans, att = error_series(run.w)
    s = np.asarray(run.s, dtype=float)
    x = res.x[idx]
    applied = res.rotor_applied_n[idx]
    m = run.metrics
    ok = bool(m["stable"] and m["completed"])
    failure = None
    if not ok:
        failure = {"text": f"{m['status']}: {m['reason']}", "t_s": float(res.t[-1]),
                   "s_m": float(s[-1]), "ned": res.x[-1, :3]}
    label = "flown on the design model (true state)"
    return FlightData(
        heading=heading,
        outcome=("completed, stable" if ok else f"FAILED: {m['status']} ({m['reason']})"),
        ok=ok, maneuver_ned=res.x[::max(1, len(res.t) // 4000), :3], maneuver_label=label,
        transverse_m=[Series(s, trans, label)], attitude_deg=[Series(s, att, label)],
        speed_m_s=Series(s, np.linalg.norm(x[:, 6:9], axis=1), "flown"),
        thrust_n=Series(s, applied.sum(axis=1), "flown (rotor forces applied)"),
        rotors_n=Series(s, applied, "applied"),
        progress=(res.t[idx], s), failure=failure)


def _phase_spans(ctrl) -> list[tuple[str, float, float]]:
    names = ctrl["phase_names"]
    code, t = ctrl["phase"], ctrl["t_s"]
    if t.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(code)) + 1
    starts = np.concatenate([[0], cuts])
    ends = np.concatenate([cuts, [t.size]])
    return [(names[int(code[a])], float(t[a]), float(t[min(b, t.size - 1)])) for a, b in zip(starts, ends)]


def _maneuver_window(ctrl) -> tuple[np.ndarray, float, float] | None:
    """(rows of the first maneuver, vehicle time it began, time it ended) or None."""
    code = ctrl["phase_names"].index("maneuver")
    rows = ctrl["phase"] == code
    if not np.any(rows):
        return None
    first = int(np.argmax(rows))
    after = np.flatnonzero(~rows[first:])
    last = first + (int(after[0]) if after.size else int(rows[first:].size)) - 1
    window = np.zeros_like(rows)
    window[first:last + 1] = True
    return window, float(ctrl["t_s"][first]), float(ctrl["t_s"][last])


def _truth_in(plan, record, t0: float, t1: float) -> dict:
    from ..model.rotation import quats_to_matrices
    from ..sim.truth import true_error_series
    sel = np.flatnonzero((record["t_s"] >= t0) & (record["t_s"] <= t1))
    sel = sel[::max(1, sel.size // MAX_TRUTH_SAMPLES)]
    quats = record.get("quaternion_wxyz")
    vel = record.get("velocity_ned_m_s")
    pos = record["position_ned_m"][sel]
    out = true_error_series(plan, pos, None if quats is None else quats_to_matrices(quats[sel]),
                            None if vel is None else vel[sel])
    out["ned"] = pos
    if vel is not None:
        out["speed_m_s"] = np.linalg.norm(vel[sel][out["index"]], axis=1)
    return out


def _failure(summary: dict | None, ctrl, record) -> dict | None:
    f = (summary or {}).get("failure")
    if not f:
        return None
    t = f.get("t_s")
    ned = None
    if t is not None:
        src_t, src_p = ((record["t_s"], record["position_ned_m"]) if record is not None
                        else (ctrl["t_s"], ctrl["x"][:, :3]))
        if src_t.size:
            ned = np.array([np.interp(t, src_t, src_p[:, k]) for k in range(3)])
    return {"text": f"{f['bound']} in {f['phase']}", "t_s": t, "s_m": f.get("s_m"), "ned": ned,
            "detail": f.get("detail", "")}


def from_fly(plan, ctrl: dict, record: dict | None, summary: dict | None, heading: str) -> FlightData:
    """``mavreg fly``'s flight: the true errors from the recording where there is one."""
    ok = (summary or {}).get("result", "ok") == "ok"
    outcome = "flown and landed" if ok else f"FAILED: {(summary or {}).get('reason', '')}"
    win = _maneuver_window(ctrl)
    spans = _phase_spans(ctrl)
    t_all = ctrl["t_s"]
    if record is not None:
        timeline = {"t_s": record["t_s"], "altitude_m": -record["position_ned_m"][:, 2],
                    "label": "true altitude", "phases": spans}
    else:
        timeline = {"t_s": t_all, "altitude_m": -ctrl["x"][:, 2], "label": "altitude (controller's state)",
                    "phases": spans}
    failure = _failure(summary, ctrl, record)
    base = dict(heading=heading, outcome=outcome, ok=ok, timeline=timeline, failure=failure)
    all_pos = record["position_ned_m"] if record is not None else ctrl["x"][:, :3]
    all_t = record["t_s"] if record is not None else t_all
    if win is None:
        phase = failure["text"] if failure else "the flight"
        return FlightData(maneuver_ned=np.zeros((0, 3)), maneuver_label="", transverse_m=[], attitude_deg=[],
                          speed_m_s=None, thrust_n=None, rotors_n=None,
                          other_ned=all_pos[::max(1, len(all_pos) // 4000)],
                          no_maneuver=f"no maneuver flown: {phase} ended it before the maneuver began", **base)
    rows, t0, t1 = win
    s_c = ctrl["s_m"][rows].astype(float)
    trans_c, att_c = error_series(ctrl["w"][rows])
    ctrl_label = "controller's own (to the nominal it flies)"
    before, after = all_pos[all_t < t0], all_pos[all_t > t1]
    step = max(1, (len(before) + len(after)) // 4000)
    other = np.vstack([before[::step], np.full((1, 3), np.nan), after[::step]])   # two pieces, not joined
    if record is not None:
        tr = _truth_in(plan, record, t0, t1)
        s_t = tr["s_m"]
        trans = [Series(s_t, tr["transverse_m"], "TRUE error (emulator's ground truth)"),
                 Series(s_c, trans_c, ctrl_label)]
        att = [Series(s_c, att_c, ctrl_label)]
        if "attitude_deg" in tr:
            att.insert(0, Series(s_t, tr["attitude_deg"], "TRUE angle to the plan's nominal attitude"))
        speed = Series(s_t, tr["speed_m_s"], "true speed") if "speed_m_s" in tr else None
        path, path_label = tr["ned"], "ground truth (maneuver)"
    else:
        trans, att = [Series(s_c, trans_c, ctrl_label)], [Series(s_c, att_c, ctrl_label)]
        speed = Series(s_c, np.linalg.norm(ctrl["x"][rows, 6:9], axis=1), "speed (controller's state)")
        path, path_label = ctrl["x"][rows, :3], "controller's state (maneuver)"
    return FlightData(maneuver_ned=path, maneuver_label=path_label, transverse_m=trans, attitude_deg=att,
                      speed_m_s=speed, thrust_n=Series(s_c, ctrl["u"][rows, 0].astype(float), "commanded"),
                      rotors_n=Series(s_c, ctrl["rotor_cmd_n"][rows].astype(float), "commanded"),
                      other_ned=other, **base)
