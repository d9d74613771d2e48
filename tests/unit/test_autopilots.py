"""Autopilot dialects: detection, heartbeat decoding, commands, telemetry requests, parameter checks.

Messages are built with pymavlink and sent through a real pack/parse round trip, so the
fields have the types the daemon receives (``param_id`` a str, ``param_value`` a float32).
The ArduCopter numbers (heartbeat at boot, default GUID_OPTIONS 0 and GUID_TIMEOUT 3) are the
ones measured on the ArduCopter SITL (``docs/autopilots.md``).
"""
from __future__ import annotations

import math
import struct

import pytest

from mavreg.daemon.vehicle.autopilots import (ARDUCOPTER, PX4, ParamChecker, choose_dialect, dialect_for,
                                      unsupported_reason)
from mavreg.daemon.vehicle.messages import mavlink2 as M

ARMED = M.MAV_MODE_FLAG_SAFETY_ARMED | M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED


def roundtrip(msg):
    """Pack ``msg`` as system 1, component 1, and parse it back."""
    tx = M.MAVLink(None, srcSystem=1, srcComponent=1)
    rx = M.MAVLink(None)
    out = rx.parse_buffer(msg.pack(tx))
    assert out and len(out) == 1
    return out[0]


def heartbeat(autopilot, vtype=M.MAV_TYPE_QUADROTOR, base_mode=0, custom_mode=0):
    return roundtrip(M.MAVLink_heartbeat_message(vtype, autopilot, base_mode, custom_mode,
                                                 M.MAV_STATE_STANDBY, 3))


def param_value(name, value, ptype=M.MAV_PARAM_TYPE_REAL32):
    return roundtrip(M.MAVLink_param_value_message(name.encode(), value, ptype, 100, 7))


def bytewise(value: int) -> float:
    """An INT32 parameter as PX4 sends it: its four bytes in the float field."""
    return struct.unpack("<f", struct.pack("<i", value))[0]


# -- detection -----------------------------------------------------------------------------
def test_dialect_from_autopilot_field():
    assert dialect_for(heartbeat(M.MAV_AUTOPILOT_PX4)) is PX4
    assert dialect_for(heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA)) is ARDUCOPTER
    assert dialect_for(heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA, M.MAV_TYPE_HEXAROTOR)) is ARDUCOPTER


def test_no_dialect_for_other_autopilots_or_ardupilot_planes():
    plane = heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA, M.MAV_TYPE_FIXED_WING, custom_mode=4)
    assert dialect_for(plane) is None        # mode 4 is not GUIDED on a plane
    assert "not a multicopter" in unsupported_reason(plane)
    gcs = heartbeat(M.MAV_AUTOPILOT_INVALID, M.MAV_TYPE_GCS)
    assert dialect_for(gcs) is None
    assert "neither PX4" in unsupported_reason(gcs)
    assert dialect_for(heartbeat(M.MAV_AUTOPILOT_GENERIC)) is None


@pytest.mark.parametrize("autopilot, choice, output, layout, words", [
    # stock autopilots: known from the HEARTBEAT; a choice may only agree
    (M.MAV_AUTOPILOT_PX4, None, "rates", PX4, None),
    (M.MAV_AUTOPILOT_PX4, "px4", "rotors", PX4, None),
    (M.MAV_AUTOPILOT_PX4, "ardupilot", "rotors", None,
     "announces PX4 (autopilot 12) but the dialect chosen is ardupilot"),
    (M.MAV_AUTOPILOT_ARDUPILOTMEGA, "ardupilot", "rates", ARDUCOPTER, None),
    (M.MAV_AUTOPILOT_ARDUPILOTMEGA, "px4", "rates", None, "announces ArduCopter (autopilot 3)"),
    # custom firmware: PX4's layout by default in the rotors output, the choice otherwise
    (M.MAV_AUTOPILOT_GENERIC, None, "rotors", PX4, "by default for the rotors output; change it with --dialect"),
    (M.MAV_AUTOPILOT_GENERIC, "ardupilot", "rotors", ARDUCOPTER, "ArduCopter's mode layout (GUIDED to fly, LAND"),
    (M.MAV_AUTOPILOT_GENERIC, "px4", "rates", PX4, "PX4's mode layout (OFFBOARD to fly, AUTO.LAND to land) as chosen"),
    (M.MAV_AUTOPILOT_GENERIC, None, "rates", None, "choose with --dialect px4|ardupilot"),
    # anything else, whatever the choice
    (M.MAV_AUTOPILOT_SLUGS, "px4", "rotors", None, "neither PX4 (12) nor ArduPilot (3)"),
    (M.MAV_AUTOPILOT_PX4, "inav", "rotors", None, "expected one of px4, ardupilot"),
])
def test_dialect_choice(autopilot, choice, output, layout, words):
    got = choose_dialect(heartbeat(autopilot), choice, output)
    if layout is None:
        assert got.dialect is None and words in got.refusal and "\n" not in got.refusal
        return
    assert got.refusal is None and got.dialect.autopilot == layout.autopilot
    assert got.dialect.offboard_mode == layout.offboard_mode
    if autopilot != M.MAV_AUTOPILOT_GENERIC:
        assert got.dialect is layout and got.notice is None
        return
    # custom firmware: the layout's modes and commands, none of its parameter rules, no rate cap
    assert words in got.notice and "not checked" in got.notice and "\n" not in got.notice
    assert got.dialect.rules == () and got.dialect.max_rate_hz == math.inf
    assert got.dialect.param_checker().verdict().state == "ok"
    assert got.dialect.set_offboard_mode(6, 1).param2 == layout.set_offboard_mode(6, 1).param2
    assert got.dialect.decode(heartbeat(0, custom_mode=6 << 16)).offboard == (layout is PX4)


# -- heartbeat decoding --------------------------------------------------------------------
def test_arducopter_heartbeat_as_measured_at_boot():
    info = ARDUCOPTER.decode(heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode=89, custom_mode=0))
    assert (info.armed, info.mode, info.offboard) == (False, "STABILIZE", False)


def test_arducopter_guided_armed_is_offboard():
    info = ARDUCOPTER.decode(heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode=ARMED, custom_mode=4))
    assert (info.armed, info.mode, info.offboard, info.custom_mode) == (True, "GUIDED", True, 4)
    land = ARDUCOPTER.decode(heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode=ARMED, custom_mode=9))
    assert (land.mode, land.offboard) == ("LAND", False)
    assert ARDUCOPTER.mode_name(99) == "MODE(99)"


def test_px4_offboard_and_the_dialects_do_not_mix():
    px4_offboard = heartbeat(M.MAV_AUTOPILOT_PX4, base_mode=ARMED, custom_mode=6 << 16)
    assert PX4.decode(px4_offboard).offboard and PX4.decode(px4_offboard).mode == "OFFBOARD"
    assert PX4.mode_name((4 << 16) | (6 << 24)) == "AUTO.LAND"
    # negative controls: each family's offboard number means nothing in the other's encoding
    assert not ARDUCOPTER.decode(px4_offboard).offboard
    guided = heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA, base_mode=ARMED, custom_mode=4)
    assert not PX4.decode(guided).offboard


# -- commands ------------------------------------------------------------------------------
def test_offboard_mode_commands():
    ap = roundtrip(ARDUCOPTER.set_offboard_mode(1, 1))
    assert (ap.command, ap.param1, ap.param2) == (M.MAV_CMD_DO_SET_MODE, 1.0, 4.0)
    px = roundtrip(PX4.set_offboard_mode(1, 1))
    assert (px.command, px.param1, px.param2) == (M.MAV_CMD_DO_SET_MODE, 1.0, 6.0)
    assert (ap.target_system, ap.target_component) == (1, 1)


def test_land_mode_commands_and_how_a_flight_ends():
    ap = roundtrip(ARDUCOPTER.set_land_mode(1, 1))
    assert (ap.command, ap.param1, ap.param2) == (M.MAV_CMD_DO_SET_MODE, 1.0, 9.0)
    assert ARDUCOPTER.mode_name(int(ap.param2)) == "LAND"
    px = roundtrip(PX4.set_land_mode(1, 1))
    assert (px.param2, px.param3) == (4.0, 6.0)
    assert PX4.mode_name((int(px.param2) << 16) | (int(px.param3) << 24)) == "AUTO.LAND"
    assert ARDUCOPTER.disarm_by_land_mode and not PX4.disarm_by_land_mode


def test_telemetry_requests_and_arducopter_rate_cap():
    reqs = [roundtrip(m) for m in ARDUCOPTER.telemetry_requests(1, 1, 100.0)]
    assert [(r.command, int(r.param1), r.param2) for r in reqs] == [
        (M.MAV_CMD_SET_MESSAGE_INTERVAL, 31, 10000.0), (M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 10000.0),
        (M.MAV_CMD_SET_MESSAGE_INTERVAL, 245, 200000.0)]
    # ArduCopter refuses more than half its 400 Hz loop (and keeps the old rate): ask for 200
    assert [r.param2 for r in ARDUCOPTER.telemetry_requests(1, 1, 400.0)][:2] == [5000.0, 5000.0]
    assert [r.param2 for r in PX4.telemetry_requests(1, 1, 400.0)][:2] == [2500.0, 2500.0]
    for bad in (0.0, -5.0, math.nan, math.inf):             # inf would make interval 0: "default rate"
        with pytest.raises(ValueError):
            ARDUCOPTER.telemetry_requests(1, 1, bad)


def test_param_requests_by_name_and_never_a_param_set():
    for dialect, names in ((ARDUCOPTER, ["GUID_OPTIONS", "GUID_TIMEOUT", "ATC_ANGLE_BOOST"]),
                           (PX4, ["COM_OF_LOSS_T", "COM_OBL_RC_ACT"])):
        reqs = [roundtrip(m) for m in dialect.param_requests(1, 1)]
        assert [r.param_id for r in reqs] == names
        assert all(r.param_index == -1 and r.get_type() == "PARAM_REQUEST_READ" for r in reqs)
        built = (dialect.param_requests(1, 1) + dialect.telemetry_requests(1, 1, 50.0)
                 + [dialect.set_offboard_mode(1, 1), dialect.set_land_mode(1, 1)])
        assert {m.get_type() for m in built} <= {"PARAM_REQUEST_READ", "COMMAND_LONG"}


# -- parameter checks ----------------------------------------------------------------------
def test_arducopter_defaults_are_refused_with_the_fix():
    chk = ARDUCOPTER.param_checker()
    assert chk.verdict().state == "waiting" and chk.verdict().missing == ("GUID_OPTIONS", "GUID_TIMEOUT",
                                                                           "ATC_ANGLE_BOOST")
    chk.add(param_value("GUID_OPTIONS", 0.0, M.MAV_PARAM_TYPE_INT32))
    v = chk.verdict()
    assert v.state == "refused" and len(v.lines) == 1
    assert "GUID_OPTIONS is 0" in v.lines[0] and "GUID_OPTIONS=8" in v.lines[0] and "climb rate" in v.lines[0]
    chk.add(param_value("GUID_TIMEOUT", 3.0))
    lines = chk.verdict().lines
    assert len(lines) == 2 and "GUID_TIMEOUT is 3 s" in lines[1] and "\n" not in "".join(lines)


def test_arducopter_good_values_pass():
    chk = ARDUCOPTER.param_checker()
    assert chk.add(param_value("GUID_OPTIONS", 9.0, M.MAV_PARAM_TYPE_INT32))    # bits 0 and 3
    assert chk.verdict().state == "waiting" and chk.verdict().missing == ("GUID_TIMEOUT", "ATC_ANGLE_BOOST")
    assert chk.add(param_value("GUID_TIMEOUT", 0.5))
    assert chk.add(param_value("ATC_ANGLE_BOOST", 0.0, M.MAV_PARAM_TYPE_INT8))
    assert chk.verdict().state == "ok"


@pytest.mark.parametrize("name,value", [("GUID_OPTIONS", 7.0), ("GUID_OPTIONS", 16.0),
                                        ("GUID_TIMEOUT", 1.5), ("GUID_TIMEOUT", 0.0),
                                        ("GUID_TIMEOUT", math.nan), ("ATC_ANGLE_BOOST", 1.0)])
def test_arducopter_bad_values_refused(name, value):
    chk = ARDUCOPTER.param_checker()
    chk.add(param_value("GUID_OPTIONS", 8.0))
    chk.add(param_value("GUID_TIMEOUT", 1.0))
    chk.add(param_value("ATC_ANGLE_BOOST", 0.0))
    assert chk.verdict().state == "ok"
    chk.add(param_value(name, value))                   # a later value replaces the earlier one
    v = chk.verdict()
    assert v.state == "refused" and v.lines[0].startswith(name)


def test_px4_integer_parameter_bytewise():
    chk = PX4.param_checker()
    chk.add(param_value("COM_OF_LOSS_T", 1.0))
    chk.add(param_value("COM_OBL_RC_ACT", bytewise(5), M.MAV_PARAM_TYPE_INT32))
    assert chk.values["COM_OBL_RC_ACT"] == 5.0 and chk.verdict().state == "ok"
    chk.add(param_value("COM_OBL_RC_ACT", bytewise(7), M.MAV_PARAM_TYPE_INT32))
    v = chk.verdict()
    assert v.state == "refused" and "COM_OBL_RC_ACT is 7" in v.lines[0] and "Disarm" in v.lines[0]
    # negative control: read as a cast float, PX4's "7 = Disarm" would look like 0 (Position) and pass
    cast = ParamChecker(PX4.rules, bytewise=False)
    cast.add(param_value("COM_OF_LOSS_T", 1.0))
    cast.add(param_value("COM_OBL_RC_ACT", bytewise(7), M.MAV_PARAM_TYPE_INT32))
    assert cast.verdict().state == "ok"


def test_px4_loss_timeout_bounds_and_real32_action():
    chk = PX4.param_checker()
    chk.add(param_value("COM_OBL_RC_ACT", 4.0))          # REAL32 (the emulator): no reinterpretation
    chk.add(param_value("COM_OF_LOSS_T", 5.0))
    v = chk.verdict()
    assert v.state == "refused" and v.lines == (v.lines[0],) and "COM_OF_LOSS_T is 5 s" in v.lines[0]
    chk.add(param_value("COM_OF_LOSS_T", 0.25))
    assert chk.verdict().state == "ok"


def test_other_messages_and_parameters_ignored():
    chk = ARDUCOPTER.param_checker()
    assert not chk.add(heartbeat(M.MAV_AUTOPILOT_ARDUPILOTMEGA))
    assert not chk.add(param_value("GUID_OPTIONX", 8.0))
    assert not chk.add(param_value("FS_GCS_ENABLE", 0.0))
    assert chk.values == {} and chk.verdict().state == "waiting"


def test_timeout_turns_missing_parameters_into_refusals():
    chk = PX4.param_checker()
    chk.add(param_value("COM_OF_LOSS_T", 0.5))
    assert chk.verdict().state == "waiting"               # the caller's wait is not over
    v = chk.verdict(timed_out=True)
    assert v.state == "refused" and v.missing == ("COM_OBL_RC_ACT",)
    assert len(v.lines) == 1 and v.lines[0].startswith("COM_OBL_RC_ACT: no answer")
    chk.add(param_value("COM_OBL_RC_ACT", bytewise(5), M.MAV_PARAM_TYPE_INT32))
    assert chk.verdict(timed_out=True).state == "ok"      # nothing missing: the timeout changes nothing
