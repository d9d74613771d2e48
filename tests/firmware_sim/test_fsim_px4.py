"""firmware_sim as a PX4 vehicle towards a ground station: status streams and their rates,
SET_MESSAGE_INTERVAL, REQUEST_MESSAGE, the parameter protocol, take-off and land, the peer rule.

In process and in vehicle time: the engine of the command line, its link replaced by one that
keeps what is sent, stepped one control period at a time (docs/firmware_sim.md, 'Talking to it
like a PX4 vehicle')."""
from __future__ import annotations

import math
from collections import Counter

import pytest
from pymavlink.dialects.v20 import common as M

from firmware_sim import modes
from firmware_sim.px4 import CAPABILITIES, EARTH_RADIUS_M, PARAMS

from tests.helpers.emulator import GCS, Client, Emulator, Vehicle


def _count(msgs) -> Counter:
    return Counter(m.get_type() for m in msgs)


def test_each_status_message_is_present_at_its_rate():
    v = Vehicle()
    c = _count(v.run(2.0))
    assert c["ATTITUDE"] == c["ATTITUDE_QUATERNION"] == c["LOCAL_POSITION_NED"] == 1000   # every period
    assert c["GLOBAL_POSITION_INT"] == 100 and c["EXTENDED_SYS_STATE"] == 10
    assert c["SYS_STATUS"] == 4 and c["HOME_POSITION"] == 1 and c["HEARTBEAT"] == 2
    m = next(m for m in v.engine.link.sent if m.get_type() == "SYS_STATUS")
    assert m.onboard_control_sensors_health & M.MAV_SYS_STATUS_PREARM_CHECK      # on the ground: armable
    for bit in (M.MAV_SYS_STATUS_SENSOR_3D_GYRO, M.MAV_SYS_STATUS_SENSOR_GPS):
        assert m.onboard_control_sensors_present & m.onboard_control_sensors_enabled \
            & m.onboard_control_sensors_health & bit
    assert 16000 < m.voltage_battery <= 16800 and m.battery_remaining == 100


def test_set_message_interval_changes_the_rate():
    v = Vehicle()
    gpi = M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, gpi, 1e5) == M.MAV_RESULT_ACCEPTED          # 10 Hz
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, -1) == M.MAV_RESULT_ACCEPTED           # LPN off
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_SYS_STATUS, 1e5) == M.MAV_RESULT_ACCEPTED
    c = _count(v.run(2.0))
    assert c["GLOBAL_POSITION_INT"] == 20 and c["LOCAL_POSITION_NED"] == 0 and c["SYS_STATUS"] == 20
    assert c["ATTITUDE_QUATERNION"] == 1000 and v.engine.complete_released == 0   # no complete sample
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, gpi, 0) == M.MAV_RESULT_ACCEPTED             # default
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, 32, 1.0) == M.MAV_RESULT_ACCEPTED           # as fast as it goes
    c = _count(v.run(1.0))
    assert c["GLOBAL_POSITION_INT"] == 50 and c["LOCAL_POSITION_NED"] == 500
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_BATTERY_STATUS, 1e5) == M.MAV_RESULT_UNSUPPORTED
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, gpi, -5) == M.MAV_RESULT_DENIED
    assert v.ack(M.MAV_CMD_SET_MESSAGE_INTERVAL, gpi, math.nan) == M.MAV_RESULT_DENIED


def test_request_message_is_answered():
    v = Vehicle()
    assert v.ack(M.MAV_CMD_REQUEST_MESSAGE, 32) == M.MAV_RESULT_FAILED     # no state published yet
    v.run(0.002)
    out = v.command(M.MAV_CMD_REQUEST_MESSAGE, 32)
    assert [m.get_type() for m in out] == ["COMMAND_ACK", "LOCAL_POSITION_NED"]
    out = v.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert [m.get_type() for m in out] == ["COMMAND_ACK", "AUTOPILOT_VERSION"]
    assert out[0].result == M.MAV_RESULT_ACCEPTED and out[0].target_system == GCS
    caps = out[1].capabilities
    assert caps == CAPABILITIES and caps & M.MAV_PROTOCOL_CAPABILITY_MAVLINK2 \
        and caps & M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT and caps & M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    assert caps & M.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET            # body rates and thrust
    assert not caps & (M.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | M.MAV_PROTOCOL_CAPABILITY_MISSION_INT)
    out = v.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_HOME_POSITION)
    assert [m.get_type() for m in out] == ["COMMAND_ACK", "HOME_POSITION"]
    assert out[1].latitude == 473977420 and out[1].altitude == 488000
    out = v.command(M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1)
    assert [m.get_type() for m in out] == ["COMMAND_ACK", "AUTOPILOT_VERSION"]
    assert v.ack(M.MAV_CMD_REQUEST_MESSAGE, 395) == M.MAV_RESULT_UNSUPPORTED   # COMPONENT_INFORMATION
    assert v.ack(M.MAV_CMD_REQUEST_MESSAGE, math.inf) == M.MAV_RESULT_UNSUPPORTED
    out = v.send(M.MAVLink_command_int_message(1, 1, 0, M.MAV_CMD_REQUEST_MESSAGE, 0, 0,
                                               M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 0, 0, 0, 0, 0, 0))
    assert [m.get_type() for m in out] == ["COMMAND_ACK", "EXTENDED_SYS_STATE"]     # COMMAND_INT too
    assert out[1].landed_state == M.MAV_LANDED_STATE_ON_GROUND


def _values(out) -> dict:
    return {m.param_id: (m.param_value, m.param_index, m.param_count) for m in out if m.get_type() == "PARAM_VALUE"}


def test_parameter_list_read_and_set_round_trip():
    v = Vehicle("--offboard-loss-timeout-s", "0.3")
    listed = _values(v.send(M.MAVLink_param_request_list_message(1, 1)))
    assert sorted(listed) == sorted(p.name for p in PARAMS)
    assert {i for _, i, _ in listed.values()} == set(range(len(PARAMS)))
    assert all(n == len(PARAMS) for _, _, n in listed.values())
    assert listed["COM_OF_LOSS_T"][0] == pytest.approx(0.3) and listed["MIS_TAKEOFF_ALT"][0] == 2.5
    out = _values(v.send(M.MAVLink_param_set_message(1, 1, b"COM_OF_LOSS_T", 0.5, M.MAV_PARAM_TYPE_REAL32)))
    assert out["COM_OF_LOSS_T"][0] == 0.5 and v.ap.cfg.offboard_loss_timeout_s == 0.5
    out = _values(v.send(M.MAVLink_param_set_message(1, 1, b"COM_OF_LOSS_T", 1e6, M.MAV_PARAM_TYPE_REAL32)))
    assert out["COM_OF_LOSS_T"][0] == 0.5 and v.ap.cfg.offboard_loss_timeout_s == 0.5     # refused, old value
    index = [p.name for p in PARAMS].index("MIS_TAKEOFF_ALT")
    out = _values(v.send(M.MAVLink_param_request_read_message(1, 1, b"", index)))
    assert list(out) == ["MIS_TAKEOFF_ALT"]
    out = _values(v.send(M.MAVLink_param_request_read_message(1, 1, b"MPC_LAND_SPEED", -1)))
    assert out["MPC_LAND_SPEED"][0] == pytest.approx(v.ap.cfg.land_descent_m_s)
    before = v.ap.drops["unsupported"]
    assert v.send(M.MAVLink_param_request_read_message(1, 1, b"NO_SUCH", -1)) == []
    assert v.send(M.MAVLink_param_request_read_message(1, 1, b"", 99)) == []
    assert v.ap.drops["unsupported"] == before + 2


def _flight_log(v: Vehicle):
    states: list = []

    def each(vehicle):
        for m in vehicle.engine.link.sent[-12:]:
            if m.get_type() == "EXTENDED_SYS_STATE" and (not states or states[-1] != m.landed_state):
                states.append(m.landed_state)
    return states, each


def test_takeoff_hold_land_disarm_and_the_landed_states():
    v = Vehicle()
    assert v.ack(M.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 7) == M.MAV_RESULT_DENIED           # disarmed
    assert v.ack(M.MAV_CMD_NAV_LAND, 0, 0, 0, math.nan) == M.MAV_RESULT_DENIED
    assert v.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, math.nan) == M.MAV_RESULT_ACCEPTED   # MAVSDK's NaN
    assert v.ack(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, math.inf) == M.MAV_RESULT_DENIED
    states, each = _flight_log(v)
    assert v.ack(M.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 7) == M.MAV_RESULT_ACCEPTED
    assert v.ap.mode == modes.TAKEOFF
    v.run(6.0, each)
    assert v.ap.mode == modes.HOLD and v.ap.armed
    assert v.engine.sim.state[2] == pytest.approx(-2.5, abs=0.15)                        # MIS_TAKEOFF_ALT
    assert v.ack(M.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 7) == M.MAV_RESULT_DENIED           # in the air
    status = [m for m in v.engine.link.sent if m.get_type() == "SYS_STATUS"]
    hover_a = 0.5 + 1.2 * v.engine.sim.params.vehicle.mass_kg * 9.80665                  # the battery model
    assert status[0].current_battery == 50 and status[-1].current_battery == pytest.approx(100 * hover_a, rel=0.05)
    assert status[-1].voltage_battery < status[0].voltage_battery - 150                 # 0.02 ohm sag
    gpi = [m for m in v.engine.link.sent if m.get_type() == "GLOBAL_POSITION_INT"][-1]
    assert gpi.relative_alt == pytest.approx(2500, abs=150) and gpi.alt == pytest.approx(490500, abs=150)
    assert v.ack(M.MAV_CMD_NAV_LAND, 0, 0, 0, math.nan) == M.MAV_RESULT_ACCEPTED
    v.run(8.0, each)
    assert not v.ap.armed and v.engine.sim.on_ground
    assert v.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED    # param7 AMSL
    assert v.ack(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 492.0) == M.MAV_RESULT_ACCEPTED
    v.run(5.0)
    assert v.ap.mode == modes.HOLD and v.engine.sim.state[2] == pytest.approx(-4.0, abs=0.15)
    assert states == [M.MAV_LANDED_STATE_ON_GROUND, M.MAV_LANDED_STATE_TAKEOFF, M.MAV_LANDED_STATE_IN_AIR,
                      M.MAV_LANDED_STATE_LANDING, M.MAV_LANDED_STATE_ON_GROUND]


def test_a_takeoff_target_below_the_minimum_climbs_to_mis_takeoff_alt():
    """As PX4's navigator, and what MAVSDK's generic path (a relative height in param7) gets."""
    v = Vehicle()
    assert v.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    out = v.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 3.0)
    assert out[0].result == M.MAV_RESULT_ACCEPTED and b"minimum" in out[1].text.encode()
    assert v.ap.mode == modes.TAKEOFF and v.ap.stab.z_ref_m == -2.5


def test_home_is_set_at_arming_and_global_position_is_converted_around_it():
    v = Vehicle("--home", "10,20,100", "--start", "x_m=100,y_m=-50,z_m=-7")
    v.run(0.02)
    gpi = [m for m in v.engine.link.sent if m.get_type() == "GLOBAL_POSITION_INT"][-1]
    assert gpi.lat == pytest.approx((10 + math.degrees(100 / EARTH_RADIUS_M)) * 1e7, abs=2)
    east_deg = math.degrees(-50 / (EARTH_RADIUS_M * math.cos(math.radians(10))))
    assert gpi.lon == pytest.approx((20 + east_deg) * 1e7, abs=2)
    assert gpi.alt == pytest.approx(107000, abs=20) and gpi.relative_alt == pytest.approx(7000, abs=20)
    w = Vehicle()
    w.engine.sim.state = (3.0, 4.0, 0.0) + tuple(w.engine.sim.state[3:])
    assert w.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    home = w.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_HOME_POSITION)[1]
    assert (home.x, home.y) == (3.0, 4.0) and home.latitude > 473977420


def test_a_ground_station_that_is_not_a_configured_peer_is_not_obeyed():
    v = Vehicle()
    for sysid in (7, 255):                         # not configured: no ack, counted, not armed
        assert v.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, system_id=sysid) == []
        assert v.send(M.MAVLink_param_request_list_message(1, 1), system_id=sysid) == []
    assert v.ap.drops["foreign_system"] == 4 and not v.ap.armed
    assert v.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, system_id=GCS) == M.MAV_RESULT_ACCEPTED
    assert v.command(M.MAV_CMD_NAV_TAKEOFF, *[math.nan] * 7, system_id=9) == []      # unconfigured
    out = v.send(M.MAVLink_command_long_message(3, 1, M.MAV_CMD_NAV_TAKEOFF, 0, *[math.nan] * 7))
    assert out == [] and v.ap.drops["wrong_target"] == 1                           # another vehicle's


def test_over_udp_commands_need_the_peer_flag():
    """The link's peer filter too: MAVSDK's 245 without --peer-system-id is dropped."""
    for flags, expected in (((), None), (("--peer-system-id", "245"), M.MAV_RESULT_ACCEPTED)):
        with Emulator("--world", "ideal", "--control-rate-hz", "100", *flags) as em:
            c = Client(em.port, system_id=245, component_id=190)
            try:
                c.heartbeat()
                c.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
                if expected is None:
                    assert c.recv(1.0) is None                  # not even telemetry: not a peer
                else:
                    assert c.ack(M.MAV_CMD_REQUEST_MESSAGE) == expected
                    assert c.wait_for("AUTOPILOT_VERSION").capabilities == CAPABILITIES
            finally:
                c.close()


def _position_target(n, e, d, mask=0b100111111000, frame=1):
    """MAVSDK's set_position_ned: velocities, accelerations and yaw rate masked."""
    return M.MAVLink_set_position_target_local_ned_message(0, 1, 1, frame, mask, n, e, d, 0, 0, 0, 0, 0, 0,
                                                           math.radians(90.0), 0)


def test_offboard_position_set_points_from_a_ground_station():
    v = Vehicle()
    drops0 = dict(v.ap.drops)
    v.send(_position_target(0, 0, -3, mask=0b100000111000))                    # with accelerations
    v.send(_position_target(0, 0, -3, frame=8))                                 # body frame
    v.send(_position_target(math.nan, 0, -3))
    v.send(_position_target(0, 0, -3), system_id=9)                             # not a peer
    assert {k: v.ap.drops[k] - drops0[k] for k in ("unsupported", "non_finite", "foreign_system")} == \
        {"unsupported": 2, "non_finite": 1, "foreign_system": 1} and v.ap.setpoint is None
    assert v.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1, math.nan) == M.MAV_RESULT_ACCEPTED
    assert v.ack(M.MAV_CMD_DO_SET_MODE, 1, modes.MAIN_OFFBOARD, 0) == M.MAV_RESULT_DENIED   # no set-point yet
    v.send(_position_target(2, 1, -3))
    assert v.ack(M.MAV_CMD_DO_SET_MODE, 1, modes.MAIN_OFFBOARD, 0) == M.MAV_RESULT_ACCEPTED  # as MAVSDK's start

    def stream(vehicle):                      # 20 Hz, as MAVSDK's offboard plugin
        if vehicle.engine.sim.step_count % 50 == 0:
            vehicle.send(_position_target(2, 1, -3))
    v.run(8.0, stream)
    s = v.engine.sim.state
    assert v.ap.mode == modes.OFFBOARD and (s[0], s[1], s[2]) == pytest.approx((2, 1, -3), abs=0.1)
    assert v.ap.stab.yaw_ref_rad == pytest.approx(math.radians(90.0))
    v.run(0.4)                                                    # the stream stops: COM_OF_LOSS_T 0.25 s
    assert v.ap.mode == modes.HOLD and v.ap.failsafe


def test_offboard_velocity_set_points():
    """MAVSDK's set_velocity_ned: positions, accelerations and yaw rate masked."""
    v = Vehicle()
    up = M.MAVLink_set_position_target_local_ned_message(0, 1, 1, 1, 0b100111000111, 0, 0, 0, 0.5, 0, -1.0,
                                                         0, 0, 0, 0, 0)
    assert v.ack(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
    v.send(up)
    assert v.ack(M.MAV_CMD_DO_SET_MODE, 1, modes.MAIN_OFFBOARD, 0) == M.MAV_RESULT_ACCEPTED
    v.run(3.0, lambda w: w.engine.sim.step_count % 50 == 0 and w.send(up))
    s = v.engine.sim.state
    assert (s[7], s[8], s[9]) == pytest.approx((0.5, 0.0, -1.0), abs=0.05) and v.ap.mode == modes.OFFBOARD
