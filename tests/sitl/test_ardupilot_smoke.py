"""A stock ArduCopter SITL through mavreg's dialect: detection, parameter check, GUIDED, arming.

The SITL is found by ``harness/ardupilot_sitl.py`` (``MAVREG_ARDUPILOT_DIR``); without
it the slow test is skipped with the reason. It runs in real time: about 45 s, most of it
waiting for EKF3 to use GPS (GUIDED refuses to arm before).
"""
from __future__ import annotations

import socket

import pytest

from harness.ardupilot_sitl import (TEST_PARAMS, ArduPilotSitl, SitlError, _alive, ardupilot_dir, free_instance,
                                    require_ardupilot)
from harness.ardupilot_sitl import arducopter_sitl_fixture  # noqa: F401  (the fixture arducopter_sitl)
from mavreg.daemon.vehicle.autopilots import ARDUCOPTER, dialect_for
from mavreg.daemon.vehicle.messages import arm_disarm, mavlink2 as M


def read_params(sitl, dialect, timeout_s=5.0):
    """Send the dialect's PARAM_REQUEST_READs and feed replies to a checker until it decides."""
    checker = dialect.param_checker()
    for msg in dialect.param_requests(sitl.sysid, sitl.compid):
        sitl.send(msg)
    sitl.wait_for(lambda m: checker.add(m) and checker.verdict().state != "waiting", timeout_s,
                  "the checked parameters")
    return checker.verdict()


@pytest.mark.slow
def test_arducopter_sitl_dialect_params_guided_arm(arducopter_sitl):
    sitl = arducopter_sitl
    hb = sitl.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1, 5, "heartbeat")
    dialect = dialect_for(hb)
    assert dialect is ARDUCOPTER
    info = dialect.decode(hb)
    assert not info.armed and not info.offboard

    assert read_params(sitl, dialect).state == "ok"
    sitl.set_param("GUID_TIMEOUT", 3)              # negative control: ArduCopter's default
    refused = read_params(sitl, dialect)
    assert refused.state == "refused" and refused.lines[0].startswith("GUID_TIMEOUT is 3 s")
    sitl.set_param("GUID_TIMEOUT", TEST_PARAMS["GUID_TIMEOUT"])

    for msg in dialect.telemetry_requests(sitl.sysid, sitl.compid, 100.0):
        sitl.send(msg)
    sitl.wait_for(lambda m: m.get_type() == "ATTITUDE_QUATERNION", 5, "ATTITUDE_QUATERNION")

    sitl.send(dialect.set_offboard_mode(sitl.sysid, sitl.compid))
    sitl.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
                  and dialect.decode(m).offboard, 5, "GUIDED in the heartbeat")
    sitl.send(arm_disarm(sitl.sysid, sitl.compid, True))       # the fixture's "ready" means armable
    ack = sitl.wait_for(lambda m: m.get_type() == "COMMAND_ACK"
                        and m.command == M.MAV_CMD_COMPONENT_ARM_DISARM, 5, "arming ACK")
    assert ack.result == M.MAV_RESULT_ACCEPTED, sitl.texts[-3:]
    hb = sitl.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
                       and dialect.decode(m).armed, 5, "armed heartbeat")
    assert dialect.decode(hb).mode == "GUIDED"
    sitl.send(arm_disarm(sitl.sysid, sitl.compid, False))      # on the ground: accepted
    sitl.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
                  and not dialect.decode(m).armed, 5, "disarmed heartbeat")
    pid = sitl.pid
    sitl.stop()                                    # what the fixture's teardown does (twice is harmless)
    assert not _alive(pid), "the SITL outlived stop()"


def test_missing_sitl_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setenv("MAVREG_ARDUPILOT_DIR", str(tmp_path))
    assert ardupilot_dir() is None
    with pytest.raises(SitlError, match="MAVREG_ARDUPILOT_DIR"):
        with ArduPilotSitl():
            pass
    with pytest.raises(pytest.skip.Exception, match="ArduCopter SITL not found"):
        require_ardupilot()


def test_instance_with_a_taken_port_is_skipped():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        try:
            taken.bind(("0.0.0.0", 5501 + 10 * 41))
        except OSError:
            pytest.skip("port of instance 41 in use by somebody else")
        assert free_instance(41, 42) == 42
        with pytest.raises(SitlError, match="no free SITL instance"):
            free_instance(41, 41)
