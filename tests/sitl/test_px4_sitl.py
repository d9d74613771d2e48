"""mavreg flies a stock PX4 (v1.16, SIH: PX4's own simulator inside the autopilot) through
body rates and thrust only, judged by SIH's ground truth (HIL_STATE_QUATERNION).

Slow (real time: PX4's boot, EKF2, take-off, a hop, landing: about 80 s a flight) and skipped
where the PX4 SITL is absent (harness/px4_sitl.py says where it is looked for). EKF2 flies
on the harness's motion-capture feed: on SIH's GPS and barometer its estimate wanders 0.3-1 m,
and the take-off or the hold leaves the envelope's 0.5 m by that alone (docs/autopilots.md).
``python -m scripts.px4.fly --flights 5`` flies the campaigns docs/autopilots.md quotes.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from harness.px4_flight import (fly_on_px4, glitch_mid_maneuver, kill_and_restart, kill_mid_maneuver,
                                     truth_touchdowns, ulog_texts)
from harness.px4_sitl import require_px4

HOP = Path(__file__).with_name("px4_hop.yaml")
TOUCHDOWN_MAX_M_S = 1.0


def _no_motor_stop_and_soft_touchdowns(out: Path) -> list:
    downs = truth_touchdowns(out)
    assert downs, "the truth saw no landing"
    assert max(v for _, v in downs) < TOUCHDOWN_MAX_M_S, downs
    return downs


@pytest.mark.slow
def test_a_hop_on_a_stock_px4_from_arming_to_its_own_disarm(tmp_path):
    """Connect, the parameter check (PX4's defaults pass), the streams, OFFBOARD, arming,
    take-off by thrust, the hold, a 4 m line, the landing, and the flight ended the PX4 way
    (a disarm once its land detector agrees, or AUTO.LAND): every phase in mavreg's summary and
    in PX4's own .ulg, and on the truth no touchdown at 1 m/s or more."""
    require_px4()
    s = fly_on_px4(HOP, tmp_path / "flight", position_source="mocap")
    phases = [e["phase"] for e in s["events"] if e["kind"] == "phase"]
    assert phases[0] == "takeoff" and "maneuver" in phases and phases[-1] == "disarmed", phases
    assert not any(e["kind"] == "motors_stopped" for e in s["events"])
    ulogs = list((tmp_path / "flight").glob("*.ulg"))
    assert ulogs, "PX4 wrote no .ulg"
    # every phase change in PX4's own log too, in order, as mavreg's STATUSTEXTs
    in_ulog = [t.split(":")[1].strip() for t in ulog_texts(ulogs[0]) if t.startswith("mavreg phase:")]
    assert in_ulog == phases, (in_ulog, phases)
    truth = s["px4_truth"]
    assert truth is not None and truth["samples"] > 100              # the hop judged on SIH's truth
    assert abs(truth["ground_height_offset_m"]) < 1.0
    _no_motor_stop_and_soft_touchdowns(tmp_path / "flight")


@pytest.mark.slow
def test_mavreg_killed_mid_maneuver_px4_takes_over_and_lands(tmp_path):
    """SIGKILL the daemon 2 s into the maneuver: PX4's offboard-loss failsafe
    (``COM_OF_LOSS_T`` 1 s, then ``COM_OBL_RC_ACT`` 4: Land, as docs/autopilots.md suggests)
    takes the vehicle, lands it and disarms; the truth sees a soft touchdown."""
    require_px4()
    r = kill_mid_maneuver(HOP, tmp_path / "kill", after_s=2.0, params={"COM_OBL_RC_ACT": 4}, position_source="mocap")
    assert r["killed_at_wall_s"] is not None, "the daemon ended before it was killed"
    assert r["disarmed"], r["modes"]
    assert any(m.startswith("AUTO.LAND") for m in r["modes"]), r["modes"]
    _no_motor_stop_and_soft_touchdowns(tmp_path / "kill")


@pytest.mark.slow
@pytest.mark.parametrize("glitch_s", [None, 0.5], ids=["for-good", "half-a-second"])
def test_a_position_source_that_jumps_mid_maneuver_ends_safely_not_in_a_crash(tmp_path, glitch_s):
    """The motion capture fed to EKF2 jumps 0.8 m 2 s into the maneuver. For good: EKF2 resets
    its position onto it, mavreg reads the jump as the position bound it is (more than the
    velocity explains), recovers, holds and lands on the shifted estimate. For half a second:
    EKF2's innovation gate rejects it and the flight goes on. Either way the truth sees a soft
    touchdown, the motors never stop in the air and the flight ends disarmed."""
    require_px4()
    r = glitch_mid_maneuver(HOP, tmp_path / "glitch", offset_m=(0.8, 0.0, 0.0), glitch_s=glitch_s)
    assert r["glitch_at_wall_s"] is not None, "the flight ended before the glitch"
    kinds = [(e["kind"], e["detail"]) for e in r["events"]]
    if glitch_s is None:
        assert any(k in ("recover", "abort") and "position_jump" in d for k, d in kinds), kinds
    else:
        assert r["result"] == "ok" or any("position_jump" in d for _, d in kinds), kinds
    assert not any(k == "motors_stopped" for k, _ in kinds), kinds
    phases = [e["phase"] for e in r["events"] if e["kind"] == "phase"]
    assert phases[-1] == "disarmed", phases
    _no_motor_stop_and_soft_touchdowns(tmp_path / "glitch")


@pytest.mark.slow
def test_a_restarted_mavreg_takes_px4_back_in_the_air_and_lands_it(tmp_path):
    """SIGKILL the daemon 2 s into the maneuver with PX4's offboard-loss action Hold
    (``COM_OBL_RC_ACT`` 5; the default, 0, is Position mode, which with no RC at all descends
    and lands), start ``mavreg fly`` again 5 s later: it
    finds PX4 armed in the air (its landed state), streams the recovery's set-points, gets
    OFFBOARD back, holds and lands; never an ARM, no disarm in the air (the truth: one
    touchdown, soft), PX4 disarmed at the end."""
    require_px4()
    r = kill_and_restart(HOP, tmp_path / "restart", after_s=2.0, restart_after_s=5.0, params={"COM_OBL_RC_ACT": 5})
    assert r["killed"], "the daemon ended before it was killed"
    assert not r["disarmed_before_restart"], r["modes_before_restart"]
    phases = [e["phase"] for e in r["events"] if e["kind"] == "phase"]
    assert phases == ["takeover", "recover", "land", "disarmed"], phases
    assert not any(e["kind"] == "motors_stopped" for e in r["events"])
    downs = _no_motor_stop_and_soft_touchdowns(tmp_path / "restart")
    assert len(downs) == 1, downs                # one flight: never put down and taken off again
