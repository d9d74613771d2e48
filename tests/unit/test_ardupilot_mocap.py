"""The ArduCopter harness's motion-capture feed (harness/ardupilot_mocap.py), without the
SITL: what it makes of a SIM_STATE, what it sends over a loopback link, and the timing settings
of its parameter file (docs/autopilots.md, "The position source")."""
from __future__ import annotations

import math
import os
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402  (MAVLINK20 must be set first)

from harness.ardupilot_mocap import HOME, MocapFeed, vision_sample  # noqa: E402
from harness.ardupilot_sitl import EXTRA_DEFAULTS, free_udp_port  # noqa: E402

M = mavutil.mavlink
NORTH_M, EAST_M, UP_M = 2.5, -1.25, 3.0


def _sim_state(mav, lat_deg: float, lon_deg: float, alt_m: float):
    """A SIM_STATE as the SITL sends it: packed and parsed, so the float32 fields are rounded."""
    msg = mav.sim_state_encode(1, 0, 0, 0, 0.1, -0.2, 1.5, 0, 0, -9.8, 0, 0, 0, lat_deg, lon_deg, alt_m,
                               0, 0, 8.0, -0.5, 0.25, round(lat_deg * 1e7), round(lon_deg * 1e7))
    parser = M.MAVLink(None)
    return parser.decode(bytearray(msg.pack(mav)))


def _point_about_home():
    lat = HOME[0] + math.degrees(NORTH_M / 6378137.0)
    lon = HOME[1] + math.degrees(EAST_M / (6378137.0 * math.cos(math.radians(HOME[0]))))
    return lat, lon, HOME[2] + UP_M


def test_a_sim_state_becomes_ned_about_home_from_the_integer_position():
    mav = M.MAVLink(None, srcSystem=1, srcComponent=1)
    m = _sim_state(mav, *_point_about_home())
    s = vision_sample(m)
    assert all(abs(a - b) < 0.01 for a, b in zip(s["position_m"], (NORTH_M, EAST_M, -UP_M))), s
    assert s["velocity_m_s"] == (8.0, -0.5, 0.25)
    assert s["euler_rad"] == tuple(float(v) for v in (m.roll, m.pitch, m.yaw))
    # negative control: the message's float32 latitude and longitude alone are decimetres off,
    # which is why the integer fields are read
    m.lat_int = m.lon_int = 0
    floats_only = vision_sample(m)["position_m"]
    assert max(abs(a - b) for a, b in zip(floats_only, (NORTH_M, EAST_M))) > 0.05


def test_the_feed_asks_for_sim_state_and_answers_each_with_position_and_speed():
    port = free_udp_port()
    feed = MocapFeed(port, rate_hz=100.0, clock_s=lambda: 12.345)
    feed.start()
    sitl = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1,
                                      dialect="ardupilotmega")
    try:
        got, deadline = {}, time.monotonic() + 5.0
        while time.monotonic() < deadline and "VISION_SPEED_ESTIMATE" not in got:
            if "COMMAND_LONG" not in got:       # the SITL speaks, without SIM_STATE
                sitl.mav.heartbeat_send(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 0)
            else:
                sitl.mav.send(_sim_state(sitl.mav, *_point_about_home()))
            m = sitl.recv_match(blocking=True, timeout=0.2)
            if m is not None:
                got.setdefault(m.get_type(), m)
    finally:
        feed.stop()
        sitl.close()
    ask = got["COMMAND_LONG"]
    assert (ask.command, ask.param1, ask.param2) == (M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_SIM_STATE, 1e4)
    pos, vel = got["VISION_POSITION_ESTIMATE"], got["VISION_SPEED_ESTIMATE"]
    assert pos.usec == vel.usec == 12345000                 # the injected clock, in microseconds
    assert abs(pos.x - NORTH_M) < 0.01 and abs(pos.y - EAST_M) < 0.01 and abs(pos.z + UP_M) < 0.01
    assert (vel.x, vel.y, vel.z) == (8.0, -0.5, 0.25)
    assert math.isnan(pos.covariance[0]) and math.isnan(vel.covariance[0])   # unknown: VISO_*_M_NSE apply
    assert feed.sent >= 1


def _params(path) -> dict:
    rows = (line.split() for line in path.read_text().splitlines() if line.strip() and not line.startswith("#"))
    return {name: float(value) for name, value in rows}


def _transport_ms(baud_param: float, nbytes: int) -> float:
    """What ArduPilot subtracts from a message's arrival time: its bytes at the port's baud, 10
    bits a byte (SERIALn_BAUD up to 2000 is in thousands)."""
    baud = {57: 57600, 115: 115200, 921: 921600}.get(int(baud_param), baud_param * 1000)
    return 1e3 * 10 * nbytes / baud


def test_the_feed_port_is_fast_enough_that_samples_are_dated_within_a_few_ms():
    p = _params(EXTRA_DEFAULTS["mocap"])
    assert p["VISO_TYPE"] == 1 and p["EK3_IMU_MASK"] == 1
    assert all(p[f"EK3_SRC1_{k}"] == 6 for k in ("POSXY", "VELXY", "POSZ", "VELZ", "YAW"))
    vision_bytes = 117 + 12                    # VISION_POSITION_ESTIMATE's payload and MAVLink 2 frame
    assert _transport_ms(p["SERIAL1_BAUD"], vision_bytes) + p["VISO_DELAY_MS"] < 5.0
    # negative control: at SERIAL1's default (57600) the same message is dated 22 ms early
    assert _transport_ms(57, vision_bytes) > 20.0
