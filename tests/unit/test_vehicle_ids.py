"""The vehicle's system id: pinned, or taken from its first autopilot HEARTBEAT on udpin, never
from a ground station's; other systems dropped and counted, and said so in one line when
they are all the daemon hears (sans-I/O: synthetic frames, an injected clock, no sockets)."""
from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.transport import signing as sg
from mavreg.daemon.vehicle.peers import (MOVE_AFTER_S, SILENCE_NOTICE_S, PeerFilter, VehicleIds, check_system_id, heartbeat_fields,
                                 system_id_to_use)
from mavreg.daemon.flight.phases import Phase
from mavreg.transport.wire import Wire
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run, wire

M = mavlink2
VEHICLE_ADDR = ("127.0.0.1", 14580)
OTHER_ADDR = ("127.0.0.1", 14581)
GCS_ADDR = ("127.0.0.1", 14550)
KEY = bytes(range(1, 33))


def hb(vtype=M.MAV_TYPE_QUADROTOR, autopilot=M.MAV_AUTOPILOT_PX4, version=3):
    return M.MAVLink_heartbeat_message(vtype, autopilot, 0, 0, M.MAV_STATE_STANDBY, version)


GCS_HB = hb(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID)
"""QGroundControl's HEARTBEAT (system 255, component 190)."""
COMPANION_HB = hb(M.MAV_TYPE_ONBOARD_CONTROLLER, M.MAV_AUTOPILOT_INVALID)


def frame(msg, sysid, compid=1):
    return Wire(sysid, compid).pack(msg)


def quat(t_ms=10):
    return M.MAVLink_attitude_quaternion_message(t_ms, 1, 0, 0, 0, 0, 0, 0, [0, 0, 0, 0])


def test_heartbeat_fields_of_trimmed_and_mavlink1_frames():
    generic = frame(hb(autopilot=M.MAV_AUTOPILOT_GENERIC, version=0), 6)   # MAVLink 2 trims its zeros
    assert generic[1] < 9 and heartbeat_fields(generic) == (M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_GENERIC)
    v1 = hb().pack(M.MAVLink(None, srcSystem=6, srcComponent=1), force_mavlink1=True)
    assert heartbeat_fields(v1) == (M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4)


def test_system_id_bounds_and_the_default_by_link():
    for bad in (0, 256, -1, 1.5, True, "6", None):
        with pytest.raises(ValueError, match="1..255"):
            check_system_id(bad)
    assert system_id_to_use("udpin:0.0.0.0:14540", None) is None          # learned
    assert system_id_to_use("udpout:127.0.0.1:14540", None) == 1           # the daemon speaks first
    assert system_id_to_use(None, None) == 1                               # the bundled emulator
    assert system_id_to_use("udpin:0.0.0.0:14540", 6) == 6
    with pytest.raises(ValueError):
        system_id_to_use("udpin:0.0.0.0:14540", 300)
    with pytest.raises(RuntimeError, match="not known yet"):
        VehicleIds(None).target


def test_udpin_locks_on_the_first_autopilot_heartbeat_never_a_ground_stations():
    f = PeerFilter(None, 1)
    assert f.admit(frame(GCS_HB, 255, 190), GCS_ADDR) == "foreign_system"
    assert f.admit(frame(hb(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID), 255, 1), GCS_ADDR) == "foreign_system"
    assert f.admit(frame(hb(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_GENERIC), 254, 1), GCS_ADDR) == "foreign_system"
    assert f.admit(frame(COMPANION_HB, 7, 1), GCS_ADDR) == "foreign_system"
    assert f.admit(frame(quat(), 6), VEHICLE_ADDR) == "foreign_system"      # no id from a state
    assert f.admit(frame(hb(), 6, 2), VEHICLE_ADDR) == "foreign_system"    # not the autopilot's component
    assert f.ids == (None, 1) and f.addr is None
    assert f.admit(frame(hb(), 6), VEHICLE_ADDR) is None                   # stock PX4, MAV_SYS_ID 6
    assert f.ids == (6, 1) and f.addr == VEHICLE_ADDR and f.vehicle_heard
    # after the lock: a second vehicle is another system, the vehicle's ids elsewhere another address
    assert f.admit(frame(hb(), 9), OTHER_ADDR) == "foreign_system"
    assert f.admit(frame(quat(), 9), VEHICLE_ADDR) == "foreign_system"
    assert f.admit(frame(quat(), 6), OTHER_ADDR) == "foreign_address"
    assert f.admit(frame(quat(), 6), VEHICLE_ADDR) is None
    assert f.heard.frames == {255: 2, 254: 1, 7: 1, 6: 2, 9: 2}
    assert f.heard.vehicles() == [9]             # 6 was last heard from component 2 (before the lock)


def test_with_signing_only_an_authenticated_heartbeat_names_the_vehicle():
    s = sg.Verifier(KEY, 10**13)
    f = PeerFilter(None, 1, signing=type("S", (), {"check": staticmethod(s.check)})())
    assert f.admit(frame(hb(), 6), VEHICLE_ADDR) == "unsigned" and f.ids == (None, 1)
    assert f.heard.frames == {}                                            # unauthenticated: not even heard
    ok = sg.Signer(KEY, lambda: 0, 10**13, 0).sign(frame(hb(), 6))
    assert f.admit(ok, VEHICLE_ADDR) is None and f.ids == (6, 1)


def test_a_known_address_must_also_name_the_system():
    f = PeerFilter(None, 1, VEHICLE_ADDR)
    assert f.admit(frame(hb(), 9), OTHER_ADDR) == "foreign_address" and f.ids == (None, 1)
    assert f.admit(frame(hb(), 6), VEHICLE_ADDR) is None and f.ids == (6, 1)


def test_only_other_systems_heard_is_said_once_within_seconds():
    """Pinned to 1, a PX4 with MAV_SYS_ID 6 sends: after SILENCE_NOTICE_S one line names what
    was heard and the flag that flies it; once. Unpinned, only a ground station: the line says
    none of them is an autopilot."""
    f = PeerFilter(1, 1)
    assert f.silence_notice(0.0) is None                                   # nothing heard at all
    f.admit(frame(hb(), 6), VEHICLE_ADDR)
    f.admit(frame(GCS_HB, 255, 190), GCS_ADDR)
    assert f.silence_notice(10.0) is None                                  # the clock starts now
    assert f.silence_notice(10.0 + SILENCE_NOTICE_S - 0.01) is None
    line = f.silence_notice(10.0 + SILENCE_NOTICE_S)
    assert line.startswith("nothing from the vehicle's system id 1 (--vehicle-system-id) in 2.0 s")
    assert "system 6 (1 frames; HEARTBEAT of component 1: type 2, autopilot 12)" in line
    assert "system 255" in line and "a ground station" in line
    assert line.endswith("to fly it, --vehicle-system-id 6") and "\n" not in line
    assert f.silence_notice(20.0) is None                                  # said once

    f = PeerFilter(None, 1)
    f.admit(frame(GCS_HB, 255, 190), GCS_ADDR)
    f.silence_notice(0.0)
    line = f.silence_notice(SILENCE_NOTICE_S)
    assert line.startswith("no autopilot HEARTBEAT") and "none is an autopilot" in line
    assert "--vehicle-system-id N" in line

    f = PeerFilter(None, 1)                                                 # a flood of ids: one short line
    for sysid in range(2, 256):
        f.admit(frame(hb(), sysid, 2), GCS_ADDR)
    f.silence_notice(0.0)
    line = f.silence_notice(SILENCE_NOTICE_S)
    assert "and 248 more systems" in line and len(line) < 1000 and "none is an autopilot" in line

    f = PeerFilter(None, 1)                                                 # the vehicle is heard: nothing to say
    f.admit(frame(GCS_HB, 255, 190), GCS_ADDR)
    f.admit(frame(hb(), 6), VEHICLE_ADDR)
    f.silence_notice(0.0)
    assert f.silence_notice(5.0) is None


def test_the_supervisor_takes_the_id_of_the_first_autopilot_heartbeat_and_addresses_it():
    """A GCS heartbeat first, then a vehicle with system id 6: the supervisor flies system 6
    (every command and set-point addressed to it); a second vehicle after that is dropped and
    counted and changes nothing."""
    sup = make_supervisor(FakePlan(), vehicle_system_id=None)
    assert sup.handle(wire(GCS_HB, 255, 190), 0.0).messages == []
    assert sup.handle(wire(COMPANION_HB, 6, 191), 0.0).messages == []
    assert sup.counters.foreign_dropped == 2 and sup.ids.system_id is None
    veh = SimVehicle(system_id=6)
    events, _, sent = run(sup, veh, 4.0)
    assert sup.ids.system_id == 6 and sup.phase == Phase.TAKEOFF and veh.armed and veh.wrong_target == 0
    (lock,) = [e for e in events if e.kind == "vehicle_id"]
    assert "vehicle system id 6" in lock.detail and "--vehicle-system-id" in lock.detail
    targeted = [m for _, m in sent if hasattr(m, "target_system") and m.get_type() != "TIMESYNC"]
    assert targeted and {m.target_system for m in targeted} == {6}
    assert {"COMMAND_LONG", "SET_ACTUATOR_CONTROL_TARGET", "PARAM_REQUEST_READ"} <= {m.get_type() for m in targeted}
    before, x = sup.counters.foreign_dropped, sup.last_sample.x.copy()
    other = SimVehicle(system_id=9)
    other.x[:3] = (40.0, 40.0, -40.0)
    for m in [other.heartbeat(), *other.telemetry()]:
        out = sup.handle(m, veh.t_ms / 1000)
        assert out.messages == [] and out.events == []
    assert sup.counters.foreign_dropped == before + 3 and (sup.last_sample.x == x).all()


def test_a_pinned_id_hears_nothing_from_another_system():
    sup = make_supervisor(FakePlan(), vehicle_system_id=1)
    veh = SimVehicle(system_id=6)
    events, _, sent = run(sup, veh, 2.0)
    assert sent == [] and events == [] and sup.ids.system_id == 1 and not veh.armed
    assert sup.counters.foreign_dropped > 500


@pytest.mark.parametrize("impl", ["fast", "reference"])
def test_a_udpin_link_takes_the_vehicles_id_and_sends_as_it(impl):
    """Both links (fed directly, no socket): a GCS datagram, then the vehicle's HEARTBEAT as
    system 6; what the daemon then sends carries system id 6."""
    from mavreg.daemon.vehicle.link import FastLink
    from mavreg.daemon.vehicle.link_reference import MavlinkLink
    got, sent = [], []
    if impl == "fast":
        sock = type("S", (), {"sendto": lambda self, d, a: sent.append(bytes(d)), "close": lambda self: None})()
        link = FastLink("udpin", None, None, 1, lambda m, t: got.append(m), None, sock)
    else:
        link = MavlinkLink("udpin", None, None, 1, lambda m, t: got.append(m), None)
        link.transport = type("T", (), {"sendto": lambda self, d, a: sent.append(bytes(d)),
                                        "is_closing": lambda self: False, "close": lambda self: None})()
    assert not link.send(hb())                                            # nobody to send to yet
    link.datagram_received(frame(GCS_HB, 255, 190), GCS_ADDR)
    link.datagram_received(frame(hb(), 6) + frame(quat(), 6), VEHICLE_ADDR)
    link.datagram_received(frame(hb(), 9), OTHER_ADDR)
    assert [m.get_srcSystem() for m in got] == [6, 6] and link.system_id == 6
    assert link.counters.foreign_system == 1 and link.counters.foreign_address == 1
    assert link.send(M.MAVLink_command_long_message(6, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    (out,) = M.MAVLink(None).parse_buffer(sent[0])
    assert out.get_srcSystem() == 6 and out.get_srcComponent() == 191
    link.close()


def test_udpout_needs_a_system_id():
    import asyncio

    from mavreg.daemon.vehicle.link import open_link
    with pytest.raises(ValueError, match="on udpout the vehicle's system id must be given"):
        asyncio.run(open_link("udpout:127.0.0.1:14540", None, 1, lambda m, t: None, None))


MOVED_ADDR = ("127.0.0.1", 40123)
"""Where a rebooted autopilot sends from (ArduCopter's SITL opens its UDP sockets again)."""


def test_a_learned_address_moves_with_the_vehicles_heartbeat_only_after_a_silence():
    f = PeerFilter(None, 1)
    assert f.admit(frame(hb(M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_ARDUPILOTMEGA), 1), VEHICLE_ADDR, 10.0) is None
    assert f.admit(frame(quat(), 1), VEHICLE_ADDR, 10.5) is None
    # while the vehicle talks from its address, its ids elsewhere are another sender's
    assert not f.may_move(11.0)
    assert f.admit(frame(hb(), 1), MOVED_ADDR, 11.0) == "foreign_address"
    assert f.admit(frame(hb(), 1), MOVED_ADDR, 10.5 + 1.9) == "foreign_address" and f.addr == VEHICLE_ADDR
    assert f.notice(12.4) is None
    # silent for MOVE_AFTER_S: a state, a ground station's or a companion's HEARTBEAT does not move it
    t = 10.5 + MOVE_AFTER_S
    assert f.may_move(t)
    assert f.admit(frame(quat(), 1), MOVED_ADDR, t) == "foreign_address"
    assert f.admit(frame(GCS_HB, 1, 1), MOVED_ADDR, t) == "foreign_address"
    assert f.admit(frame(COMPANION_HB, 1, 1), MOVED_ADDR, t) == "foreign_address"
    assert f.admit(frame(hb(), 9), MOVED_ADDR, t) == "foreign_system"
    # its autopilot HEARTBEAT does, once, and the old address is then another sender's
    assert f.admit(frame(hb(), 1), MOVED_ADDR, t) is None and f.addr == MOVED_ADDR and f.moves == 1
    assert f.admit(frame(quat(), 1), MOVED_ADDR, t + 0.01) is None
    assert f.admit(frame(quat(), 1), VEHICLE_ADDR, t + 0.02) == "foreign_address"
    line = f.notice(t + 0.1)
    assert "40123" in line and "14580" in line and "silent for 2.0 s" in line and f.notice(t + 0.2) is None


def test_a_given_address_never_moves_nor_does_one_without_a_clock():
    given = PeerFilter(1, 1, VEHICLE_ADDR)
    assert given.admit(frame(hb(), 1), VEHICLE_ADDR, 0.0) is None
    assert not given.may_move(100.0) and given.admit(frame(hb(), 1), MOVED_ADDR, 100.0) == "foreign_address"
    learned = PeerFilter(None, 1)
    assert learned.admit(frame(hb(), 1), VEHICLE_ADDR) is None          # no clock given: never moves
    assert learned.admit(frame(hb(), 1), MOVED_ADDR, 100.0) == "foreign_address" and learned.moves == 0


@pytest.mark.parametrize("impl", ["fast", "reference"])
def test_a_udpin_link_follows_a_rebooted_vehicle_to_its_new_port(impl, monkeypatch):
    """Both links, fed directly with an injected clock: the vehicle heard, silent 2 s, then its
    HEARTBEAT from a new port: taken, counted, and what the daemon sends goes there."""
    from mavreg.daemon.vehicle import link as link_module
    from mavreg.daemon.vehicle.link import FastLink
    from mavreg.daemon.vehicle.link_reference import MavlinkLink
    now = [100.0]
    monkeypatch.setattr(link_module.time, "perf_counter_ns", lambda: int(now[0] * 1e9))
    got, sent = [], []
    if impl == "fast":
        sock = type("S", (), {"sendto": lambda self, d, a: sent.append(a), "close": lambda self: None})()
        link = FastLink("udpin", None, None, 1, lambda m, t: got.append(m), None, sock)
    else:
        link = MavlinkLink("udpin", None, None, 1, lambda m, t: got.append(m), None)
        link.transport = type("T", (), {"sendto": lambda self, d, a: sent.append(a),
                                        "is_closing": lambda self: False, "close": lambda self: None})()
    link.datagram_received(frame(hb(), 1), VEHICLE_ADDR)
    now[0] += 1.0
    link.datagram_received(frame(hb(), 1), MOVED_ADDR)                  # the vehicle still there
    assert link.counters.foreign_address == 1 and link.vehicle_addr == VEHICLE_ADDR
    now[0] += MOVE_AFTER_S
    link.datagram_received(frame(hb(), 1) + frame(quat(), 1), MOVED_ADDR)
    assert len(got) == 3 and link.vehicle_addr == MOVED_ADDR and link.counters.vehicle_moved == 1
    assert link.send(hb()) and sent[-1] == MOVED_ADDR
    link.close()
