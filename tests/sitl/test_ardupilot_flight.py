"""mavreg flies a stock ArduCopter (its SITL) through body rates and thrust only: take-off,
the barrel roll, landing and disarm, judged by the SITL's own ground truth (SIM_STATE).

Slow (about 2 minutes in real time: EKF start, take-off, maneuver, landing) and skipped
where the ArduCopter SITL is absent (harness/ardupilot_sitl.py says where it is
looked for). ``python -m scripts.ardupilot.fly --flights 5 [--position-source mocap]`` flies the
campaigns the docs quote.
"""
from __future__ import annotations

import pytest

from mavreg.config.paths import maneuver_file
from harness.ardupilot_flight import fly_on_ardupilot
from harness.ardupilot_sitl import require_ardupilot

LOOP_MAX_M = 0.30
"""The loop's true error bound of this test: 18.8-24.0 cm measured over 11 flights. Most of it is
the autopilot's estimate (EKF3 on GPS at 4-5 g), not the controller: on the SITL's truth as
the estimate the loop is 9-13 cm (docs/autopilots.md). The aim is 10 cm."""
MOCAP_LOOP_MAX_M = 0.10
"""The loop's true error bound with the harness's motion-capture feed as EKF3's position source
and ``freestyle_mocap.yaml``: 6.6-7.6 cm over 5 flights (docs/autopilots.md), the goal."""


@pytest.mark.slow
@pytest.mark.parametrize("position_source, loop_max_m", [("gps", LOOP_MAX_M), ("mocap", MOCAP_LOOP_MAX_M)],
                         ids=["gps", "mocap"])
def test_barrel_roll_on_a_stock_arducopter(tmp_path, position_source, loop_max_m):
    require_ardupilot()
    s = fly_on_ardupilot(maneuver_file("barrel_roll"), tmp_path / "flight", position_source=position_source)
    assert s["result"] == "ok", s["reason"]
    assert s["exit_code"] == 0
    truth = s["ardupilot_truth"]
    assert truth is not None and truth["samples"] > 1000         # the maneuver was judged on SIM_STATE
    assert truth["segments"]["loop"]["max_m"] <= loop_max_m, truth["segments"]["loop"]
    assert s["touchdown_speed_m_s"] is not None and s["touchdown_speed_m_s"] < 1.0
    assert truth["lowest_altitude_m"] > -0.2                     # never below the ground it took off from
    assert not any(e["kind"] == "motors_stopped" for e in s["events"])


@pytest.mark.slow
def test_a_restarted_mavreg_takes_the_arducopter_back_in_the_air_and_lands_it(tmp_path):
    """SIGKILL the daemon 1 s into the barrel roll's run-up; ArduCopter stays in GUIDED, its
    ``GUID_TIMEOUT`` holding it level at zero climb rate; ``mavreg fly`` started again 3 s later
    finds it armed in the air, takes it over (GUIDED is its offboard mode: the recovery flies at
    once), brakes, holds and lands it: never an ARM, one soft touchdown on SIM_STATE, disarmed
    at the end."""
    from harness.ardupilot_flight import kill_and_restart_on_ardupilot
    require_ardupilot()
    r = kill_and_restart_on_ardupilot(maneuver_file("barrel_roll"), tmp_path / "restart", after_s=1.0,
                                      restart_after_s=3.0)
    assert r["killed"], "the daemon ended before it was killed"
    phases = [e["phase"] for e in r["events"] if e["kind"] == "phase"]
    assert phases[:3] == ["takeover", "recover", "land"] and phases[-1] == "disarmed", phases
    assert not any(e["kind"] == "motors_stopped" for e in r["events"])
    assert len(r["touchdowns"]) == 1 and r["touchdowns"][0][1] < 1.0, r["touchdowns"]
