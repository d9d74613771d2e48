"""The ground-station forwarder (sans-I/O): what reaches a ground station, what reaches the vehicle."""
from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.paths import maneuver_file
from mavreg.daemon.vehicle import messages as mm
from mavreg.daemon.gcs.bridge import GcsHub, GcsParams, parse_gcs_url
from mavreg.daemon.gcs.policy import DROP, FORWARD, LAND, REFUSE, judge
from mavreg.daemon.flight.phases import Event

VEHICLE = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
GCS = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)


def _from(mav, msg):
    """``msg`` as a receiver decodes it (bytes, header and ids of ``mav``)."""
    frame = msg.pack(mav)
    parser = mavlink2.MAVLink(None)
    return parser.parse_buffer(frame)[0]


def _parse(datagrams):
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    out = []
    for data, n in datagrams:
        got = parser.parse_buffer(data) or []
        assert len(got) == n
        out.extend(got)
    return out


def _attitude(t_ms):
    return _from(VEHICLE, mavlink2.MAVLink_attitude_quaternion_message(t_ms, 1, 0, 0, 0, 0, 0, 0, [0] * 4))


def _command(cmd, *params):
    p = list(params) + [0.0] * (7 - len(params))
    return mavlink2.MAVLink_command_long_message(1, 1, cmd, 0, *p)


def test_vehicle_messages_reach_the_ground_station_unchanged():
    hub = GcsHub(2, GcsParams(), system_id=1)
    hb = _from(VEHICLE, mavlink2.MAVLink_heartbeat_message(2, 12, 129, 6 << 16, 4, 3))
    text = _from(VEHICLE, mavlink2.MAVLink_statustext_message(6, b"mode OFFBOARD: by command", 0, 0))
    att = _attitude(100)
    for m in (hb, text, att):
        hub.vehicle_message(m, 0.0)
    for i in (0, 1):                                  # every endpoint gets its own copy
        dgrams = hub.drain(i, 0.0)
        assert b"".join(d for d, _ in dgrams) == hb.get_msgbuf() + text.get_msgbuf() + att.get_msgbuf()
        got = _parse(dgrams)
        assert [(m.get_type(), m.get_srcSystem(), m.get_srcComponent()) for m in got] == [
            ("HEARTBEAT", 1, 1), ("STATUSTEXT", 1, 1), ("ATTITUDE_QUATERNION", 1, 1)]
        assert got[0].custom_mode == 6 << 16
    assert hub.drain(0, 0.1) == []


def test_daemon_heartbeat_phase_and_statustexts_as_component_191():
    hub = GcsHub(1, GcsParams(), system_id=3)
    hub.heartbeat(mm.daemon_heartbeat(True), "maneuver", 1.0)
    safety = mm.statustext(mm.SEVERITY_CRITICAL, "mavreg recover: attitude 61 deg", 7)
    actuator = mm.actuator_target(5, 3, 1, [0.3] * 4)
    ev = Event(12.5, "phase", "hold", float("nan"), "take-off complete, holding")
    other = Event(12.5, "vehicle", "hold", float("nan"), "vehicle armed")
    hub.daemon_output(safety + [actuator], [ev, other], 1.0)
    got = _parse(hub.drain(0, 1.0))
    assert {(m.get_srcSystem(), m.get_srcComponent()) for m in got} == {(3, 191)}
    assert [m.get_type() for m in got] == ["HEARTBEAT", "NAMED_VALUE_INT", "STATUSTEXT", "STATUSTEXT",
                                           "NAMED_VALUE_INT"]
    assert got[0].type == mavlink2.MAV_TYPE_ONBOARD_CONTROLLER
    assert got[1].name == "mr_phase" and got[1].value == 4          # PHASE_CODES["maneuver"]
    assert got[2].text == "mavreg recover: attitude 61 deg" and got[2].severity == mm.SEVERITY_CRITICAL
    assert got[3].text == "mavreg phase hold: take-off complete, holding"
    assert got[4].name == "mr_phase" and got[4].value == 2          # the new phase at once
    assert [m.get_seq() for m in got] == [0, 1, 2, 3, 4]           # one sequence of its own


def test_streams_are_rate_limited_events_are_not():
    hub = GcsHub(1, GcsParams(stream_rate_hz=20.0, max_messages_per_s=1e6, burst_messages=10_000,
                              queue_len=10_000), system_id=1)
    hb = _from(VEHICLE, mavlink2.MAVLink_heartbeat_message(2, 12, 129, 0, 4, 3))
    for k in range(1000):                              # 1 s of 1 kHz attitude and 1 kHz heartbeats
        hub.vehicle_message(_attitude(k), k * 1e-3)
        hub.vehicle_message(hb, k * 1e-3)
    got = _parse(hub.drain(0, 1.0))
    att = [m for m in got if m.get_type() == "ATTITUDE_QUATERNION"]
    assert len(att) == 20                              # one per 50 ms
    assert [m.time_boot_ms for m in att] == list(range(0, 1000, 50))
    assert sum(m.get_type() == "HEARTBEAT" for m in got) == 1000
    assert hub.endpoints[0].counters.dropped_rate == 980


def test_bounded_queue_and_token_bucket_drop_never_block():
    p = GcsParams(stream_rate_hz=1e6, max_messages_per_s=100.0, burst_messages=10, queue_len=50)
    hub = GcsHub(1, p, system_id=1)
    for k in range(200):                               # nobody drains: a dead ground station
        hub.vehicle_message(_attitude(k), k * 1e-5)
    ep = hub.endpoints[0]
    assert len(ep.queue) == 50 and ep.counters.dropped_queue == 150
    text = _from(VEHICLE, mavlink2.MAVLink_statustext_message(2, b"impact", 0, 0))
    hub.vehicle_message(text, 0.01)                    # an event displaces the oldest frame
    assert len(ep.queue) == 50 and ep.queue[-1] == bytes(text.get_msgbuf())
    first = hub.drain(0, 0.01)
    assert sum(n for _, n in first) == 10              # the burst
    assert hub.drain(0, 0.01) == []                    # no token left
    assert sum(n for _, n in hub.drain(0, 0.11)) == 10  # 0.1 s at 100 /s
    assert all(len(d) <= p.max_datagram_bytes for d, _ in first)


def test_datagrams_respect_the_size_bound():
    hub = GcsHub(1, GcsParams(), system_id=1)
    for k in range(60):
        hub.text(6, f"message {k} " + "x" * 30, 0.0)
    dgrams = hub.drain(0, 0.0)
    assert len(dgrams) > 1 and all(len(d) <= 1400 for d, _ in dgrams)
    assert len(_parse(dgrams)) == 60


def test_read_only_by_default_drops_and_counts_everything():
    hub = GcsHub(1, GcsParams(), system_id=1)
    msgs = [mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3),
            _command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1.0),
            _command(mavlink2.MAV_CMD_REQUEST_MESSAGE, 148.0),
            mavlink2.MAVLink_param_request_list_message(1, 1),
            _command(mavlink2.MAV_CMD_NAV_LAND)]
    data = b"".join(m.pack(GCS) for m in msgs)
    res = hub.receive(0, data, 0.0, in_control=True)
    assert res.forward == [] and not res.land
    c = hub.endpoints[0].counters
    assert (c.from_gcs, c.dropped_never, c.dropped_read_only, c.to_vehicle) == (5, 1, 4, 0)
    replies = _parse(hub.drain(0, 0.0))
    acks = [m for m in replies if m.get_type() == "COMMAND_ACK"]
    assert [(a.command, a.result, a.target_system) for a in acks] == [
        (mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, mavlink2.MAV_RESULT_DENIED, 255),
        (mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAV_RESULT_DENIED, 255),
        (mavlink2.MAV_CMD_NAV_LAND, mavlink2.MAV_RESULT_DENIED, 255)]
    notes = [m.text for m in replies if m.get_type() == "STATUSTEXT"]
    assert len(notes) == 1 and "read-only" in notes[0]
    hub.receive(0, data, 1.0, in_control=True)         # the explanation is rate-limited
    assert not any(m.get_type() == "STATUSTEXT" for m in _parse(hub.drain(0, 1.0)))


def test_allowed_commands_pass_except_those_that_fight_the_daemon():
    hub = GcsHub(1, GcsParams(allow_commands=True), system_id=1)
    query = [_command(mavlink2.MAV_CMD_REQUEST_MESSAGE, 148.0),
             mavlink2.MAVLink_param_request_list_message(1, 1)]
    fight = [_command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0.0, 21196.0),
             _command(mavlink2.MAV_CMD_DO_SET_MODE, 1.0, 4.0, 3.0),                # AUTO.LOITER
             mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, [1.0] * 8),
             mavlink2.MAVLink_set_mode_message(1, 1, 6 << 16),
             mavlink2.MAVLink_param_set_message(1, 1, b"MPC_XY_P", 9.0, 9)]
    data = b"".join(m.pack(GCS) for m in query + fight)
    res = hub.receive(0, data, 0.0, in_control=True)
    assert [m.get_type() for m in res.forward] == ["COMMAND_LONG", "PARAM_REQUEST_LIST"]
    assert res.forward[0].command == mavlink2.MAV_CMD_REQUEST_MESSAGE and not res.land
    c = hub.endpoints[0].counters
    assert (c.refused, c.to_vehicle, c.dropped_read_only) == (5, 2, 0)
    # the flight is over (disarmed or aborted): the vehicle is the ground station's again
    res = hub.receive(0, data, 10.0, in_control=False)
    assert len(res.forward) == len(query + fight)
    # the ground station's HEARTBEAT and TIMESYNC never pass
    hb = mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(GCS)
    ts = mavlink2.MAVLink_timesync_message(0, 5).pack(GCS)
    assert hub.receive(0, hb + ts, 11.0, in_control=False).forward == []


@pytest.mark.parametrize("msg", [
    _command(mavlink2.MAV_CMD_NAV_LAND),
    _command(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH),
    _command(mavlink2.MAV_CMD_DO_SET_MODE, 1.0, 4.0, 6.0),                        # AUTO.LAND
    mavlink2.MAVLink_set_mode_message(1, 1, (4 << 16) | (5 << 24)),                 # AUTO.RTL
], ids=["nav_land", "rtl", "mode_land", "set_mode_rtl"])
def test_land_and_rtl_become_the_daemons_landing(msg):
    hub = GcsHub(1, GcsParams(allow_commands=True), system_id=1)
    res = hub.receive(0, msg.pack(GCS), 0.0, in_control=True)
    assert res.land and res.forward == []
    assert hub.endpoints[0].counters.land_requests == 1
    texts = [m.text for m in _parse(hub.drain(0, 0.0)) if m.get_type() == "STATUSTEXT"]
    assert texts == ["mavreg gcs: land requested; the daemon lands"]
    assert judge(_from(GCS, msg), True, False)[0] == FORWARD       # after the flight: the vehicle's own


def test_garbage_from_the_ground_station_is_counted():
    hub = GcsHub(1, GcsParams(allow_commands=True), system_id=1)
    good = _command(mavlink2.MAV_CMD_REQUEST_MESSAGE, 148.0).pack(GCS)
    for junk in (b"\x00" * 5, b"\xfd\x09garbage-not-a-frame" * 3, good[:-3], bytes(range(256))):
        res = hub.receive(0, junk, 0.0, in_control=True)
        assert res.forward == []
    assert hub.endpoints[0].counters.bad_data > 0
    hub2 = GcsHub(1, GcsParams(allow_commands=True), system_id=1)
    assert len(hub2.receive(0, good, 0.0, in_control=True).forward) == 1


def test_messages_outside_the_common_dialect_never_pass():
    from pymavlink.dialects.v20 import ardupilotmega as apm
    other = apm.MAVLink(None, srcSystem=255, srcComponent=190)
    frame = apm.MAVLink_rally_fetch_point_message(1, 1, 0).pack(other)
    hub = GcsHub(1, GcsParams(allow_commands=True), system_id=1)
    assert hub.receive(0, frame, 0.0, in_control=False).forward == []
    assert hub.endpoints[0].counters.dropped_unknown == 1


def test_non_finite_mode_parameters_are_refused_not_a_crash():
    hub = GcsHub(1, GcsParams(allow_commands=True), system_id=1)
    nan = float("nan")
    msg = _command(mavlink2.MAV_CMD_DO_SET_MODE, 1.0, nan, float("inf"))
    res = hub.receive(0, msg.pack(GCS), 0.0, in_control=True)
    assert res.forward == [] and not res.land and hub.endpoints[0].counters.refused == 1


def test_judge_verdicts():
    arm = _from(GCS, _command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1.0))
    assert judge(arm, False, True)[0] == DROP
    assert judge(arm, True, True)[0] == REFUSE
    assert judge(arm, True, False)[0] == FORWARD
    land = _from(GCS, _command(mavlink2.MAV_CMD_NAV_LAND))
    assert judge(land, True, True)[0] == LAND


@pytest.mark.parametrize("url,expected", [
    ("udpout:127.0.0.1:14550", ("udpout", "127.0.0.1", 14550)),
    ("udpout:10.0.0.5", ("udpout", "10.0.0.5", 14550)),
    ("udpin:0.0.0.0:14551", ("udpin", "0.0.0.0", 14551)),
])
def test_parse_gcs_url(url, expected):
    assert parse_gcs_url(url) == expected


@pytest.mark.parametrize("url", ["tcp:127.0.0.1:5760", "udpout:", "udpout:host:port", "udpout:h:0",
                                 "udpout:h:70000", "14550", "udpout:a:b:c"])
def test_parse_gcs_url_rejects_with_one_line(url):
    with pytest.raises(ValueError) as e:
        parse_gcs_url(url)
    assert "--gcs" in str(e.value) and "\n" not in str(e.value)


def test_fly_and_serve_take_gcs_options():
    from mavreg.cli.common import gcs_config
    from mavreg.cli.main import build_parser
    parser, _ = build_parser()
    maneuver = str(maneuver_file("barrel_roll"))
    for argv in (["serve"], ["fly", maneuver]):
        args = parser.parse_args(argv + ["--gcs", "udpout:127.0.0.1", "--gcs", "udpin:0.0.0.0:14551",
                                         "--gcs-allow-commands"])
        cfg = gcs_config(args)
        assert cfg["gcs_urls"] == ("udpout:127.0.0.1", "udpin:0.0.0.0:14551")
        assert cfg["gcs"].allow_commands
        plain = gcs_config(parser.parse_args(argv))
        assert plain["gcs_urls"] == () and not plain["gcs"].allow_commands
        with pytest.raises(ValueError, match="needs a --gcs"):
            gcs_config(parser.parse_args(argv + ["--gcs-allow-commands"]))
