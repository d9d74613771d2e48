"""Per-flight safety metrics of the robustness experiment on synthetic truth recordings."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mavreg.experiments.robustness_metrics import (altitude_above_takeoff, judge_flight, judging_window,
                                                   lowest_altitude, motors_stopped_in_air, touchdowns)

DT = 0.001
HOVER_N = 1.84


def _phase(t, phase):
    return {"kind": "phase", "time_s": t, "phase": phase}


def _record(path, alt, vz_up, applied, armed, ground, exit_code=0, z0=0.05):
    """Write a recording as firmware_sim's (vertical motion only; take-off point at NED z0)."""
    n = alt.size
    pos = np.zeros((n, 3))
    pos[:, 2] = z0 - alt
    vel = np.zeros((n, 3))
    vel[:, 2] = -vz_up
    np.savez(path, t_s=np.arange(n) * DT, position_ned_m=pos, velocity_ned_m_s=vel,
             quaternion_wxyz=np.tile([1.0, 0, 0, 0], (n, 1)), rotor_applied_n=applied, armed=armed,
             on_ground=ground, meta_json=np.array(json.dumps({"exit_code": exit_code, "stop_reason": "test"})))
    return path


def _clean_flight():
    """1 s on the ground, climb to 3 m (2 s), hold and fly (10 s), descend at 0.3 m/s, 1 s on the ground."""
    alt = np.concatenate([np.zeros(1000), np.linspace(0, 3, 2000), np.full(10000, 3.0),
                          np.linspace(3, 0, 10000), np.zeros(1000)])
    vz = np.gradient(alt, DT)
    ground = alt <= 0.0
    ground[1000:1001] = True
    applied = np.full((alt.size, 4), HOVER_N)
    armed = np.ones(alt.size, bool)
    armed[-500:] = False
    applied[-500:] = 0.0
    applied[:900] = 0.0
    armed[:900] = False
    events = [_phase(0.9, "takeoff"), _phase(3.0, "hold"), _phase(5.0, "run_in"), _phase(6.0, "maneuver"),
              _phase(10.0, "hold"), _phase(13.0, "land"), _phase(23.5, "disarmed")]
    return alt, vz, applied, armed, ground, events


def test_a_clean_flight_is_safe_and_its_lowest_altitude_is_the_hold(tmp_path):
    alt, vz, applied, armed, ground, events = _clean_flight()
    applied[8000:8020] = 0.0                         # a 20 ms blip of idle rotors in the air: not a stop
    rec = _record(tmp_path / "g.npz", alt, vz, applied, armed, ground)
    j = judge_flight({"result": "ok", "reason": "", "failure": None, "events": events, "flight_time_s": 23.0},
                     rec)
    assert j["result"] == "ok" and j["first_bound"] is None
    assert j["lowest_altitude_m"] == pytest.approx(3.0, abs=1e-3)     # hold to landing
    assert j["judged_from_to_s"] == [3.0, 13.0]
    assert len(j["touchdowns"]) == 1 and j["max_touchdown_speed_m_s"] == pytest.approx(0.3, abs=0.01)
    assert j["ground_impact"] is False
    assert j["motors_stopped_in_air"] is False and j["motors_stopped_event_t_s"] is None


def test_motors_stopped_in_the_air_and_the_fall_that_follows(tmp_path):
    alt, vz, applied, armed, ground, events = _clean_flight()
    k = 9000                                          # at 3 m, 9 s: disarmed, the rotors spin down
    fall_t = np.arange(alt.size - k) * DT
    alt[k:] = np.maximum(3.0 - 0.5 * 9.81 * fall_t ** 2, 0.0)
    vz[k:] = -9.81 * fall_t
    end = k + int(np.flatnonzero(alt[k:] <= 0.0)[0])  # the emulator stops at the crash: no contact recorded
    armed[k:] = False
    applied[k:] = HOVER_N * np.exp(-fall_t / 0.02)[:, None]
    events = events[:4] + [{"kind": "motors_stopped", "time_s": 9.0}, _phase(9.0, "terminate")]
    rec = _record(tmp_path / "g.npz", alt[:end], vz[:end], applied[:end], armed[:end], ground[:end],
                  exit_code=3)
    j = judge_flight({"result": "failed", "reason": "attitude_error in maneuver ...",
                      "failure": {"bound": "attitude_error", "phase": "maneuver", "action": "motors stopped"},
                      "events": events}, rec)
    assert j["motors_stopped_in_air"] is True
    assert j["motors_stopped_in_air_at"]["t_s"] == pytest.approx(9.0, abs=1e-3)
    assert j["motors_stopped_in_air_at"]["altitude_m"] == pytest.approx(3.0, abs=1e-3)
    assert j["motors_stopped_event_t_s"] == 9.0 and j["first_bound"] == "attitude_error"
    assert j["ground_impact"] is True and j["max_touchdown_speed_m_s"] == pytest.approx(np.sqrt(2 * 9.81 * 3), rel=0.01)
    assert j["lowest_altitude_m"] == pytest.approx(3.0, abs=1e-3)     # judged until the motors stopped


def test_a_hard_touchdown_is_an_impact_and_a_landing_is_not():
    t = np.arange(6) * DT
    v = np.zeros((6, 3))
    v[:3, 2] = 2.0                                    # 2 m/s down, then the ground zeroes it
    g = np.array([True, False, False, True, True, True])
    assert touchdowns(t, v, g) == [(0.003, 2.0)]
    v[:3, 2] = 0.3
    assert touchdowns(t, v, g) == [(0.003, pytest.approx(0.3))]
    assert touchdowns(t, v, np.ones(6, bool)) == []                  # never left the ground
    assert touchdowns(t, v, np.zeros(6, bool), crashed=True) == [(0.005, 0.0)]


def test_motors_stopped_needs_altitude_air_and_50_ms():
    t = np.arange(200) * DT
    idle = np.zeros((200, 4))
    armed = np.ones(200, bool)
    air = np.zeros(200, bool)
    assert motors_stopped_in_air(t, np.full(200, 2.0), idle, armed, air) == (0.0, 2.0)
    assert motors_stopped_in_air(t, np.full(200, 0.1), idle, armed, air) is None        # at the ground
    assert motors_stopped_in_air(t, np.full(200, 2.0), idle, armed, np.ones(200, bool)) is None  # landed
    spinning = np.full((200, 4), HOVER_N)
    assert motors_stopped_in_air(t, np.full(200, 2.0), spinning, armed, air) is None
    short = spinning.copy()
    short[100:140] = 0.0                                                                # 40 ms
    assert motors_stopped_in_air(t, np.full(200, 2.0), short, armed, air) is None
    disarmed = armed.copy()
    disarmed[120:] = False                                                              # 80 ms disarmed
    assert motors_stopped_in_air(t, np.full(200, 2.0), spinning, disarmed, air) == (0.12, 2.0)


def test_lowest_altitude_stops_at_the_ground_and_needs_a_take_off():
    t = np.arange(5.0)
    alt = np.array([0.0, 2.0, 1.5, 0.7, 0.0])
    ground = np.array([True, False, False, False, True])
    assert lowest_altitude(t, alt, ground, 1.0, 3.0) == 0.7
    assert lowest_altitude(t, alt, ground, 1.0, None) == 0.0         # the ground touched: 0
    assert lowest_altitude(t, alt, ground, None, None) is None
    assert np.allclose(altitude_above_takeoff([[0, 0, 0.1], [0, 0, -1.9]]), [0.0, 2.0])
    ev = [_phase(0.5, "takeoff"), _phase(2.0, "hold"), _phase(4.0, "maneuver"), _phase(5.0, "recover"),
          _phase(9.0, "land")]
    assert judging_window(ev) == (2.0, 9.0)
    assert judging_window([_phase(0.5, "takeoff"), _phase(1.0, "aborted")]) == (None, None)
    assert judging_window([_phase(0.5, "takeoff")]) == (None, None)


def _outcome(spec, flight_judged, status="completed"):
    """A robustness run's outcome from a judged flight (None: not flown) on a toy plan."""
    from types import SimpleNamespace as NS
    from mavreg.experiments.robustness_metrics import robustness_metrics
    from mavreg.experiments.runner import RunOutcome
    s = np.linspace(0.0, 25.0, 251)
    tangent_x = NS(length_m=25.0, evaluate=lambda q: (None, np.tile(np.eye(3), (np.size(q), 1, 1))))
    plan = NS(name="toy", laps_segment="loop", segments=[("run_up", 0.0, 10.0), ("loop", 10.0, 20.0)],
              path=tangent_x, s=s, speed_m_s=np.full(s.size, 4.8))        # flown at 5 m/s along x
    e = np.where((s >= 10) & (s < 20), 0.02, 0.05)
    trace = NS(t_s=s / 5, s_m=s, transverse_error_m=e, attitude_error_deg=np.full(s.size, 3.0))
    extra = {} if flight_judged is None else {"flight": flight_judged, "wall_time_s": 1.0}
    flight = NS(extra=extra, status=status, completed=status == "completed",
                velocity_m_s=np.tile([5.0, 0.0, 0.0], (s.size, 1)),
                reason="mavreg fly exit 2: bad argument" if flight_judged is None else "")
    return RunOutcome(spec, robustness_metrics(plan, trace, flight, spec), None)


def _judged(result="ok", impact=False, stopped=False, bound=None):
    return {"result": result, "reason": "" if result == "ok" else f"{bound} in maneuver ...; action: recovery",
            "first_bound": bound, "bound_phase": "maneuver" if bound else None, "action": "recovery" if bound else None,
            "flight_time_s": 50.0, "lowest_altitude_m": 0.0 if impact else 2.9,
            "max_touchdown_speed_m_s": 4.2 if impact else 0.3, "ground_impact": impact,
            "motors_stopped_in_air": stopped,
            "motors_stopped_in_air_at": {"t_s": 30.0, "altitude_m": 2.5} if stopped else None,
            "motors_stopped_event_t_s": 30.0 if stopped else None}


def test_each_flight_is_classed_and_the_report_lists_every_flight_that_was_not_ok(tmp_path):
    from mavreg.experiments.report import markdown, results_dict
    from mavreg.experiments.robustness import robustness
    exp = robustness(0, 1, "baseline,thrust90,loss,no-timesync,rotors-7n")
    outs = [_outcome(exp.runs[0], _judged()),
            _outcome(exp.runs[1], _judged("failed", bound="position_error"), status="failed"),
            _outcome(exp.runs[2], _judged("failed", impact=True, stopped=True, bound="rate_error"), "failed"),
            _outcome(exp.runs[3], None, status="not_flown")]
    from mavreg.experiments.runner import RunOutcome
    outs.append(RunOutcome(exp.runs[4], None, None, "ValueError: the gust missed its place", "tb"))
    ms = [o.metrics for o in outs[:4]]
    assert [m["safety"] for m in ms] == ["ok", "failed, safe", "unsafe", "not flown"]
    assert [m["ok"] for m in ms] == [True, False, False, False]
    assert ms[0]["overspeed_m_s"] == pytest.approx(0.2)          # 5 m/s flown on a 4.8 m/s profile
    assert ms[0]["maneuver_max_error_m"] == 0.05 and ms[0]["loop_max_error_m"] == 0.02
    assert ms[0]["max_attitude_error_deg"] == 3.0 and ms[0]["cause"] == ""
    assert ms[2]["cause"].startswith("motors stopped in the air at 2.5 m; hit the ground at 4.2 m/s; rate_error")
    assert ms[3]["result"] == "not flown" and "exit 2" in ms[3]["cause"]
    res = results_dict(exp, "sitl", outs, "cmd", 1, 10.0, [], {"sitl": {"world": "realistic"}})
    sm = res["summary"]
    assert (sm["ok"], sm["failed_safe"], sm["unsafe"], sm["not_flown"], sm["errors"]) == (1, 1, 1, 2, 1)
    assert sm["by_cell"]["thrust90"]["first_bounds"] == {"position_error": 1}
    assert sm["by_cell"]["baseline"]["maneuver_max_error_m"] == {"median": 0.05, "max": 0.05}
    md = markdown(res)
    not_ok = md.split("## Flights that were not ok")[1].split("## Every flight")[0]
    assert all(label in not_ok for label in ("thrust90 #0", "loss-5pct #0", "no-timesync #0", "rotors-7n #0"))
    assert "baseline #0" not in not_ok and "the gust missed its place" in not_ok
    json.dumps(res)                                    # JSON-ready
    from mavreg.experiments.robustness_figures import robustness_figures
    assert [p.name for p in robustness_figures(tmp_path, outs, exp.cells)] == ["robustness_cells.png"]
