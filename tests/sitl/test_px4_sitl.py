"""mavreg flies a stock PX4 (v1.16, SIH: PX4's own simulator inside the autopilot) through
body rates and thrust only, judged by SIH's ground truth (HIL_STATE_QUATERNION).

Slow (real time: PX4's boot, EKF2, take-off, a hop, landing: about 80 s a flight) and skipped
where the PX4 SITL is absent (tests/helpers/px4_sitl.py says where it is looked for). EKF2 flies
on the harness's motion-capture feed: on SIH's GPS and barometer its estimate wanders 0.3-1 m,
and the take-off or the hold leaves the envelope's 0.5 m by that alone (docs/autopilots.md).
``python -m scripts.px4.fly --flights 5`` flies the campaigns docs/autopilots.md quotes.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers.px4_flight import fly_on_px4, kill_mid_maneuver, truth_touchdowns, ulog_texts
from tests.helpers.px4_sitl import require_px4

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
