"""The numbers of one robustness flight: the daemon's outcome, the truth's errors and safety.

Definitions (the truth is the emulator's recording of every 1 ms physics step, from the
ground before arming to the end of the flight; altitudes are above the take-off point, the
recording's first position):

- **outcome**: ``summary.json``'s ``result`` (``ok`` or ``failed``) and its one-line reason;
  the first bound violated, its phase and the action taken (``failure``, docs/safety.md).
- **maneuver / loop error**: the largest distance from the path over the maneuver's samples
  (from the start of the maneuver phase to the phase after it), and over those in the laps
  segment (the loop; none for a maneuver without one) (:mod:`.record`). **Max attitude
  error**: over the maneuver. **Overspeed**: the largest true speed along the path over the
  profile's speed at the same s (:func:`.disturbance_metrics.overspeed`): a regulator that
  catches up after a gust shows it here.
- **lowest altitude**: the lowest true altitude from the end of the take-off (the first
  phase after it) to the first of: a landing, hand-over, disarm or motor stop (phases
  ``land``, ``aborted``, ``disarmed``, ``terminate``), the first ground contact (counted as
  0 m), the end of the recording. None when the take-off never ended.
- **touchdown speed**: the true speed just before each ground contact after lift-off (the
  largest of the last :data:`TOUCHDOWN_SAMPLES` airborne samples: the ground zeroes the
  velocity on contact); a flight the emulator ended with a crash touches down at its last
  speed. **Ground impact**: a touchdown faster than :data:`IMPACT_SPEED_M_S` (1 m/s).
- **motors stopped in the air**: for at least :data:`STOPPED_MIN_S` (50 ms) the vehicle is
  off the ground, higher than :data:`STOPPED_ALTITUDE_M` (0.2 m) and either disarmed or
  with every rotor's applied force under :data:`STOPPED_FORCE_N` (0.1 N, 1.4 % of the
  nominal hover's); the daemon's own ``motors_stopped`` event is kept beside it.
- **safety**: ``ok``; ``failed, safe`` (failed, no ground impact, motors never stopped in
  the air); ``unsafe`` (either); ``not flown`` (``mavreg fly`` left no recording). Via sim
  (the maneuver alone on the design model): ``ok`` (it reached the path's end) or ``failed``
  (diverged or timed out); the whole-flight numbers are None.
"""
from __future__ import annotations

import json

import numpy as np

from .disturbance_metrics import along_track_speed, overspeed

__all__ = ["IMPACT_SPEED_M_S", "STOPPED_FORCE_N", "STOPPED_MIN_S", "STOPPED_ALTITUDE_M", "TOUCHDOWN_SAMPLES",
           "altitude_above_takeoff", "judging_window", "load_truth", "lowest_altitude", "touchdowns",
           "motors_stopped_in_air", "judge_flight", "robustness_metrics", "SAFETY_CLASSES",
           "SIM_CLASSES"]

IMPACT_SPEED_M_S = 1.0
STOPPED_FORCE_N = 0.1
STOPPED_MIN_S = 0.05
STOPPED_ALTITUDE_M = 0.2
TOUCHDOWN_SAMPLES = 3
CRASH_EXIT_CODE = 3
"""firmware_sim's exit status for a touchdown too fast or too tilted."""
SAFETY_CLASSES = ("ok", "failed, safe", "unsafe", "not flown")
SIM_CLASSES = ("ok", "failed", "not flown")
"""Via sim (:mod:`.robustness_sim`): the maneuver reached its end (ok) or diverged or timed out
(failed); the design model has no safety layer to judge."""
_WINDOW_ENDS = ("land", "aborted", "disarmed", "terminate")


def altitude_above_takeoff(position_ned_m) -> np.ndarray:
    """Altitude (m, up) of each NED position above the first one."""
    p = np.asarray(position_ned_m, dtype=float).reshape(-1, 3)
    return -(p[:, 2] - p[0, 2]) if p.size else np.zeros(0)


def judging_window(events) -> tuple[float | None, float | None]:
    """(start, end) in vehicle time of the flight the lowest altitude is judged over: the first
    phase after the take-off, to the first phase of :data:`_WINDOW_ENDS` after it (None: none)."""
    t0 = t1 = None
    took_off = False
    for ev in events:
        if ev.get("kind") != "phase" or ev.get("time_s") is None:
            continue
        if ev["phase"] == "takeoff":
            took_off = True
        elif took_off and t0 is None:
            if ev["phase"] in _WINDOW_ENDS:
                return None, None
            t0 = float(ev["time_s"])
        elif t0 is not None and ev["phase"] in _WINDOW_ENDS:
            t1 = float(ev["time_s"])
            break
    return t0, t1


def lowest_altitude(t_s, altitude_m, on_ground, t_from: float | None, t_to: float | None) -> float | None:
    """Lowest altitude in ``[t_from, t_to]`` up to the first ground contact in it (0 m there);
    ``t_to`` None: to the end. None when ``t_from`` is None or no sample is in the window."""
    if t_from is None:
        return None
    t = np.asarray(t_s, dtype=float)
    alt = np.asarray(altitude_m, dtype=float)
    ground = np.asarray(on_ground, dtype=bool)
    sel = (t >= t_from) & (t <= (t[-1] if t_to is None else t_to)) if t.size else np.zeros(0, bool)
    idx = np.flatnonzero(sel)
    if idx.size == 0:
        return None
    hit = np.flatnonzero(ground[idx])
    if hit.size:
        return 0.0
    return float(np.min(alt[idx]))


def touchdowns(t_s, velocity_ned_m_s, on_ground, crashed: bool = False) -> list[tuple[float, float]]:
    """(time, speed) of each ground contact after a lift-off; with ``crashed``, the recording's
    last sample too (the emulator stops before it records a crash)."""
    t = np.asarray(t_s, dtype=float)
    speed = np.linalg.norm(np.asarray(velocity_ned_m_s, dtype=float).reshape(-1, 3), axis=1)
    g = np.asarray(on_ground, dtype=bool)
    out = []
    for i in np.flatnonzero(g[1:] & ~g[:-1]) + 1:
        out.append((float(t[i]), float(np.max(speed[max(0, i - TOUCHDOWN_SAMPLES):i]))))
    if crashed and t.size and not g[-1]:
        out.append((float(t[-1]), float(speed[-1])))
    return out


def motors_stopped_in_air(t_s, altitude_m, rotor_applied_n, armed, on_ground) -> tuple[float, float] | None:
    """(time, altitude) where the motors first stood still in the air (see the module
    docstring), or None."""
    t = np.asarray(t_s, dtype=float)
    if t.size == 0:
        return None
    alt = np.asarray(altitude_m, dtype=float)
    idle = np.all(np.asarray(rotor_applied_n, dtype=float).reshape(-1, 4) < STOPPED_FORCE_N, axis=1)
    mask = ~np.asarray(on_ground, dtype=bool) & (alt > STOPPED_ALTITUDE_M) & (~np.asarray(armed, bool) | idle)
    edges = np.flatnonzero(np.diff(np.r_[0, mask.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2]):          # runs [a, b) of the mask
        if t[b - 1] - t[a] >= STOPPED_MIN_S - 1e-9:
            return float(t[a]), float(alt[a])
    return None


def _meta(z) -> dict:
    try:
        return json.loads(str(z["meta_json"]))
    except (KeyError, ValueError):
        return {}


def load_truth(record_path) -> tuple:
    """``(t_s, position_ned_m, velocity_ned_m_s, rotor_applied_n, armed, on_ground, meta)`` of
    an emulator recording (``firmware_sim --record``), what the safety judges read."""
    with np.load(record_path) as z:
        return (z["t_s"], z["position_ned_m"], z["velocity_ned_m_s"], z["rotor_applied_n"], z["armed"],
                z["on_ground"], _meta(z))


def judge_flight(summary: dict, record_path) -> dict:
    """The whole flight's outcome and safety from ``summary.json`` and the emulator's
    recording (JSON-ready; see the module docstring)."""
    t, pos, vel, applied, armed, ground, meta = load_truth(record_path)
    alt = altitude_above_takeoff(pos)
    events = summary.get("events") or []
    t_from, t_to = judging_window(events)
    downs = touchdowns(t, vel, ground, crashed=meta.get("exit_code") == CRASH_EXIT_CODE)
    top = max((s for _, s in downs), default=None)
    stopped = motors_stopped_in_air(t, alt, applied, armed, ground)
    ev_stop = next((float(e["time_s"]) for e in events if e.get("kind") == "motors_stopped"
                    and e.get("time_s") is not None), None)
    fail = summary.get("failure") or {}
    return {
        "result": summary.get("result"), "reason": summary.get("reason") or "",
        "first_bound": fail.get("bound"), "bound_phase": fail.get("phase"), "action": fail.get("action"),
        "flight_time_s": summary.get("flight_time_s"), "emulator_exit_code": summary.get("emulator_exit_code"),
        "emulator_stop": meta.get("stop_reason"),
        "lowest_altitude_m": lowest_altitude(t, alt, ground, t_from, t_to),
        "judged_from_to_s": [t_from, t_to],
        "touchdowns": [[a, b] for a, b in downs[:10]],
        "max_touchdown_speed_m_s": top,
        "ground_impact": bool(top is not None and top > IMPACT_SPEED_M_S),
        "motors_stopped_in_air": stopped is not None,
        "motors_stopped_in_air_at": None if stopped is None else {"t_s": stopped[0], "altitude_m": stopped[1]},
        "motors_stopped_event_t_s": ev_stop,
        "airframe": meta.get("airframe"),          # the emulator's drawn airframe (--mismatch-seed)
    }


def _loop_mask(plan, s_m) -> np.ndarray | None:
    name = plan.laps_segment or "loop"
    spans = [(a, b) for n, a, b in plan.segments if n == name]
    if not spans:
        return None
    a, b = min(a for a, _ in spans), max(b for _, b in spans)
    return (s_m >= a) & (s_m < b)


def _peak(values) -> float | None:
    v = np.asarray(values, dtype=float)
    return float(np.max(v)) if v.size else None


def _safety(f: dict | None) -> str:
    if f is None:
        return "not flown"
    if f.get("via") == "sim":                  # the maneuver alone: reached its end or not
        return "ok" if f["result"] == "ok" else "failed"
    if f["ground_impact"] or f["motors_stopped_in_air"]:
        return "unsafe"
    return "ok" if f["result"] == "ok" else "failed, safe"


def _cause(f: dict | None, flight) -> str:
    """One line: why the flight is not ok ('' when it is)."""
    if f is None:
        return flight.reason or "not flown"
    parts = []
    if f["motors_stopped_in_air"]:
        parts.append(f"motors stopped in the air at {f['motors_stopped_in_air_at']['altitude_m']:.1f} m")
    if f["ground_impact"]:
        parts.append(f"hit the ground at {f['max_touchdown_speed_m_s']:.1f} m/s")
    if f["result"] != "ok":
        parts.append(f["reason"] or "failed")
    return "; ".join(parts)


def robustness_metrics(plan, trace, flight, spec) -> dict:
    """Every number of one robustness flight (JSON-ready); see the module docstring."""
    f = (flight.extra or {}).get("flight")
    e, att = trace.transverse_error_m, trace.attitude_error_deg
    loop = _loop_mask(plan, trace.s_m)
    safety = _safety(f)
    m = {
        "index": spec.index, "label": spec.label, "cell": spec.cell, "group": spec.group, "seed": spec.seed,
        "mismatch_seed": spec.mismatch_seed, "emulator_args": list(spec.emulator_args),
        "maneuver": plan.name, "saturation_n": spec.saturation_n,
        "gust_force_n": None if spec.gust_force_n is None else list(spec.gust_force_n),
        "maneuver_status": flight.status, "maneuver_completed": bool(flight.completed),
        "maneuver_max_error_m": _peak(e), "loop_max_error_m": None if loop is None else _peak(e[loop]),
        "max_attitude_error_deg": _peak(att),
        "overspeed_m_s": (overspeed(along_track_speed(plan.path, trace.s_m, flight.velocity_m_s), trace.s_m,
                                    plan.s, plan.speed_m_s) if trace.t_s.size else None),
        "maneuver_duration_s": float(trace.t_s[-1] - trace.t_s[0]) if trace.t_s.size else None,
        "safety": safety, "cause": "" if safety == "ok" else _cause(f, flight),
        "extra": {k: v for k, v in (flight.extra or {}).items() if k != "flight"},
    }
    keys = ("result", "reason", "first_bound", "bound_phase", "action", "flight_time_s", "lowest_altitude_m",
            "max_touchdown_speed_m_s", "ground_impact", "motors_stopped_in_air", "motors_stopped_in_air_at",
            "motors_stopped_event_t_s", "emulator_exit_code", "emulator_stop", "touchdowns",
            "judged_from_to_s", "airframe")
    m.update({k: (f or {}).get(k) for k in keys})
    if f is None:
        m.update(result="not flown", reason=flight.reason, ground_impact=None, motors_stopped_in_air=None)
    m["ok"] = safety == "ok"
    return m
