"""Every event has a time (the daemon's clock; the vehicle's once it has one), and fly's text
names the unit of every number it prints."""
from __future__ import annotations

import json
import math

from mavreg.daemon.jobs.ctrllog import ControlLog
from mavreg.daemon.flight.phases import Event
from mavreg.daemon.jobs.report import TABLE_LEGEND, format_summary


def test_an_event_before_the_vehicle_clock_prints_the_daemon_clock_not_nan():
    early = Event(math.nan, "queued", "preflight", math.nan, "maneuver queued", daemon_s=0.412)
    late = Event(0.718, "phase", "takeoff", math.nan, "take-off", daemon_s=3.101)
    assert early.line().startswith("daemon    0.412 s  ") and "nan" not in early.line()
    assert late.line().startswith("daemon    3.101 s  vehicle t=   0.718 s [takeoff]")
    assert Event(1.0, "phase", "hold", 2.5, "x").line() == "vehicle t=   1.000 s [hold] phase s=2.500 m: x"


def test_the_control_log_counts_early_events_back_on_the_vehicle_axis():
    log = ControlLog()
    log.events = [Event(math.nan, "queued", "preflight", math.nan, "q", daemon_s=1.0),
                  Event(math.nan, "vehicle", "preflight", math.nan, "hb", daemon_s=2.5),
                  Event(0.75, "phase", "takeoff", math.nan, "t", daemon_s=3.25)]
    log.clock_anchor = (3.0, 0.5)              # the first sample: daemon 3.0 s, vehicle 0.5 s
    ev = json.loads(str(log.arrays()["events_json"]))
    assert [e["time_s"] for e in ev] == [-1.5, 0.0, 0.75]
    assert [e["daemon_time_s"] for e in ev] == [1.0, 2.5, 3.25]
    log.clock_anchor = None                    # the vehicle never sent a sample: no vehicle time
    ev = json.loads(str(log.arrays()["events_json"]))
    assert ev[0]["time_s"] is None and ev[0]["daemon_time_s"] == 1.0


def _summary():
    seg = {"transverse_error_m": {"max": 0.0306, "rms": 0.0159}, "attitude_error_deg": {"max": 2.22},
           "rotor_command_n": {"max": 4.33}, "saturated_s": 0.0}
    return {"result": "ok", "maneuver": "barrel_roll", "length_m": 40.47, "flight_time_s": 59.0,
            "controller_metrics": {**seg, "segments": {"run_up": seg}},
            "ground_truth": {"max_m": 0.0303, "max_deg": 22.78, "segments": {"run_up": {"max_m": 0.0303}}},
            "events": [{"time_s": -1.25, "daemon_time_s": 0.5, "kind": "phase", "phase": "preflight",
                        "s_m": None, "detail": "early"},
                       {"time_s": 0.718, "daemon_time_s": 3.1, "kind": "phase", "phase": "takeoff",
                        "s_m": None, "detail": "take-off"}]}


def test_the_table_is_in_mm_and_explained_and_events_have_both_clocks():
    text = format_summary(_summary())
    assert "max e_t mm" in text and "true max mm" in text and " cm" not in text
    assert "30.6" in text and "22.78" in text             # 3.06 cm as 30.6 mm; degrees as they were
    assert TABLE_LEGEND in text and "true" in TABLE_LEGEND and "drag" in TABLE_LEGEND
    assert "t=  -1.250 s  daemon    0.500 s  preflight early" in text
    assert "nan" not in text
