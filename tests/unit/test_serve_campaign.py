"""The soak and chaos campaigns' draws and figures (mavreg/experiments/serve_*): draws
reproducible from a seed, hostile uploads the loader refuses, the truth's verdict on a
recording with a hard landing and with motors stopped in the air (negative controls beside a
clean one), and growth and lost results counted as defined."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.maneuver import load_maneuver_text
from mavreg.errors import UserError
from mavreg.experiments.serve_campaign import upload_text
from mavreg.experiments.serve_campaign_report import GROWTH_FROM, judge_truth, summarize
from mavreg.experiments.serve_draws import HOSTILE_UPLOADS, WORLD_FLIGHTS, draw_flights


def test_draws_are_a_function_of_the_seed_and_chaos_restarts_into_each_world():
    a = draw_flights("chaos", 11, 40)
    assert a == draw_flights("chaos", 11, 40) and a != draw_flights("chaos", 12, 40)
    assert [f.number for f in a if f.restart] == list(range(1, 41, WORLD_FLIGHTS))
    assert all(f.world == a[(f.number - 1) // WORLD_FLIGHTS * WORLD_FLIGHTS].world for f in a)
    soak = draw_flights("soak", 0, 50)
    assert not any(f.restart or f.world or f.load for f in soak)
    assert sum(bool(f.hostile) for f in soak) == 10
    with pytest.raises(ValueError, match="soak, chaos"):
        draw_flights("marathon", 0, 1)


def test_every_flight_upload_loads_and_every_hostile_one_is_refused_in_one_line():
    for f in draw_flights("soak", 3, 30):
        load_maneuver_text(upload_text(f), f.maneuver)
    for name, text in HOSTILE_UPLOADS.items():
        if name == "too_fast":
            continue                 # a valid file: the planner refuses it (infeasible speed)
        with pytest.raises((UserError, ValueError)) as err:
            load_maneuver_text(text, name)
        assert "\n" not in str(err.value)


def _recording(path, touchdown_speed=0.3, stop_motors_at=None):
    """A hop on the emulator's record layout: lift-off, 1.5 m, descent at ``touchdown_speed``."""
    t = np.arange(0.0, 20.0, 0.01)
    alt = np.clip(np.minimum(0.5 * (t - 2.0), 1.5), 0.0, None)
    descent = t > 12.0
    alt[descent] = np.clip(1.5 - touchdown_speed * (t[descent] - 12.0), 0.0, None)
    vz = np.gradient(alt, t)
    ground = alt <= 0.0
    applied = np.full((t.size, 4), 2.5)
    if stop_motors_at is not None:
        applied[(t >= stop_motors_at) & (t < stop_motors_at + 0.2)] = 0.0
    np.savez(path, t_s=t, position_ned_m=np.c_[0 * t, 0 * t, -alt], velocity_ned_m_s=np.c_[0 * t, 0 * t, -vz],
             rotor_applied_n=applied, armed=(t > 1.0) & (t < 19.0), on_ground=ground)


@pytest.mark.parametrize("case, unsafe", [({}, False), ({"touchdown_speed": 2.0}, True),
                                          ({"stop_motors_at": 8.0}, True)])
def test_the_truth_flags_a_hard_landing_and_motors_stopped_in_the_air(tmp_path, case, unsafe):
    path = tmp_path / "truth.npz"
    _recording(path, **case)
    row = {"upload": "accepted", "record": {"vehicle_span_s": [0.0, 19.5], "result": "ok",
                                            "counters": {"samples": 1, "actuator_sent": 1}}}
    judge_truth([row], path)
    truth = row["truth"]
    assert (truth["ground_impact"] or truth["motors_stopped_in_air"]) == unsafe
    assert path.exists() == unsafe               # kept only as evidence of an unsafe flight
    sm = summarize("chaos", {"rows": [{"flight": 1, **row}], "serve_exit": 0, "wall_s": 1.0})
    assert bool(sm["unsafe"]) == unsafe


def test_an_arm_in_a_flight_whose_upload_was_rejected_is_an_arm_not_asked(tmp_path):
    path = tmp_path / "truth.npz"
    _recording(path)
    row = {"upload": "rejected", "record": {"vehicle_span_s": [0.0, 19.5], "result": "not_flown"}}
    judge_truth([row], path)
    assert row["truth"]["arm_not_asked"]


def test_growth_is_measured_from_flight_20_and_lost_results_are_counted():
    rows = []
    for n in range(1, 61):
        rss = 100_000 + (5_000 if n == 45 else 0) + (50_000 if n < GROWTH_FROM else 0)
        rec = None if n == 33 else {"result": "ok", "latency_ms": {"median": 0.2, "p99": 1.0},
                                    "counters": {"samples": 10, "actuator_sent": 10}}
        rows.append({"flight": n, "upload": "accepted", "record": rec,
                     "resources": {"serve": {"rss_kb": rss, "fds": 20, "threads": 6}}})
    rows[40].update(record=None, upload="not sent")            # alive (resources read): not flown
    rows[50].update(record=None, upload="not sent", resources=None)     # the daemon gone: lost
    sm = summarize("soak", {"rows": rows, "serve_exit": 0, "wall_s": 1.0})
    assert sm["growth"]["serve_rss_kb"]["growth_pct"] == pytest.approx(5.0)   # the warm-up before 20 is not growth
    assert sm["growth"]["serve_fds"]["growth_pct"] == 0.0
    assert sm["lost_results"] == [33, 51]
    assert sm["outcomes"] == {"lost": 2, "ok": 57, "not flown: the vehicle stayed armed": 1}


def test_a_flight_handed_over_is_judged_through_its_failsafe_landing(tmp_path):
    """The daemon's last sample came at 10 s (a hand-over to the vehicle's failsafe); the
    failsafe's landing at 2 m/s comes after it and still counts against the flight."""
    path = tmp_path / "truth.npz"
    _recording(path, touchdown_speed=2.0)
    row = {"upload": "accepted", "record": {"vehicle_span_s": [0.0, 10.0], "result": "vehicle_mode",
                                            "counters": {"samples": 1, "actuator_sent": 1}}}
    judge_truth([row], path)
    assert row["truth"]["ground_impact"]
