"""The daemon's two links over real loopback sockets: the fast one agrees with the reference."""
from __future__ import annotations

import asyncio
import socket

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.vehicle.link import FastLink, io_impl, open_link
from mavreg.daemon.vehicle.link_reference import MavlinkLink
from mavreg.daemon.logs.tlog import TlogWriter

VEHICLE = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
STRANGER = mavlink2.MAVLink(None, srcSystem=7, srcComponent=1)


def _frames():
    """A heartbeat, a period's bundle, a TIMESYNC reply, garbage, a truncated frame."""
    hb = mavlink2.MAVLink_heartbeat_message(2, 12, 129, 393216, 4, 3).pack(VEHICLE)
    bundle = b"".join(m.pack(VEHICLE) for m in (
        mavlink2.MAVLink_attitude_message(10, 0.1, 0.2, 0.3, 0.0, 0.0, 0.0),
        mavlink2.MAVLink_attitude_quaternion_message(10, 1, 0, 0, 0, 0, 0, 0, [0, 0, 0, 0]),
        mavlink2.MAVLink_local_position_ned_message(10, 1, 2, -3, 0, 0, 0)))
    ts = mavlink2.MAVLink_timesync_message(12_000_000, 99).pack(VEHICLE)
    text = mavlink2.MAVLink_statustext_message(4, b"mode HOLD: by command", 0, 0).pack(VEHICLE)
    return [hb, bundle, ts + text, b"\x01\x02garbage", bundle[:-7]]


async def _until(condition, timeout_s: float = 5.0) -> None:
    """Let the event loop run until ``condition()`` holds (the link has read what was sent);
    fail after ``timeout_s``, a bound on a broken link, not a wait that the test relies on."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not condition():
        assert loop.time() < deadline, f"not within {timeout_s} s"
        await asyncio.sleep(0.001)


def _frames_in(datagrams: list[bytes]) -> int:
    """Whole MAVLink frames in ``datagrams``."""
    return len(mavlink2.MAVLink(None).parse_buffer(b"".join(datagrams)) or [])


async def _exchange(impl: str, tmp_path):
    """A vehicle socket sends the datagrams to a udpin link; the link answers with a command
    and a TIMESYNC request through send_many. Returns what the link delivered and sent."""
    got = []
    tlog = TlogWriter(tmp_path / f"{impl}.tlog")
    link = await open_link("udpin:127.0.0.1:0", 1, 1, lambda m, t: got.append(m), tlog, impl=impl)
    port = (link.sock if impl == "fast" else link.transport.get_extra_info("socket")).getsockname()[1]
    vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    vehicle.bind(("127.0.0.1", 0))
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        stranger.sendto(mavlink2.MAVLink_heartbeat_message(2, 12, 0, 0, 4, 3).pack(STRANGER), ("127.0.0.1", port))
        assert not link.send_many([mavlink2.MAVLink_timesync_message(0, 1)])   # no vehicle address yet
        for d in _frames():
            vehicle.sendto(d, ("127.0.0.1", port))
        await asyncio.wait_for(link.connected.wait(), 2.0)
        sent = 1 + len(_frames())                                            # the stranger's, the vehicle's
        await _until(lambda: link.counters.datagrams_in == sent)
        stranger.sendto(_frames()[1], ("127.0.0.1", port))                   # not the vehicle's address
        await _until(lambda: link.counters.datagrams_in == sent + 1)
        cmd = mavlink2.MAVLink_set_actuator_control_target_message(5, 0, 1, 1, [0.3, 0.3, 0.3, 0.3, 0, 0, 0, 0])
        assert link.send_many([cmd, mavlink2.MAVLink_timesync_message(0, 1234)])
        vehicle.settimeout(5.0)
        datagrams = [vehicle.recv(65535)]
        while _frames_in(datagrams) < 2:                                     # the reference sends two
            datagrams.append(vehicle.recv(65535))
        vehicle.setblocking(False)                                           # and nothing more is queued
        try:
            while True:
                datagrams.append(vehicle.recv(65535))
        except BlockingIOError:
            pass
        return got, dict(link.counters.__dict__), datagrams
    finally:
        link.close()
        tlog.close()
        vehicle.close()
        stranger.close()


def test_fast_link_delivers_what_the_reference_delivers_and_sends_one_datagram(tmp_path):
    fast = asyncio.run(_exchange("fast", tmp_path))
    ref = asyncio.run(_exchange("reference", tmp_path))
    types = lambda msgs: [m.get_type() for m in msgs]            # noqa: E731
    # udpin: only the vehicle's ids are taken (the stranger's heartbeat is dropped as a foreign
    # system), and its heartbeat names its address; the cut-short bundle gives its two whole frames
    assert types(ref[0]) == ["HEARTBEAT", "ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED",
                             "TIMESYNC", "STATUSTEXT", "ATTITUDE", "ATTITUDE_QUATERNION"]
    # the fast link does not decode ATTITUDE once a quaternion has come (the assembler ignores it)
    assert types(fast[0]) == [t for k, t in enumerate(types(ref[0])) if k != 6]
    assert [m.get_srcSystem() for m in fast[0]] == [1] * 7
    for a, b in zip(fast[0], [m for k, m in enumerate(ref[0]) if k != 6]):
        assert a == b and a.to_dict() == b.to_dict()
    # the same counters: the stranger dropped once the vehicle is known, the garbage is bad data
    assert {**fast[1], "not_decoded": 0} == ref[1] and fast[1]["not_decoded"] == 1
    assert fast[1]["foreign_address"] == 1 and fast[1]["bad_data"] == 1 and fast[1]["foreign_system"] == 1
    assert fast[1]["messages_in"] == 8 and fast[1]["messages_out"] == 2
    # the fast link packs the command and the TIMESYNC request into one datagram, the reference two
    assert len(fast[2]) == 1 and len(ref[2]) == 2 and fast[2][0] == b"".join(ref[2])
    parser = mavlink2.MAVLink(None)
    assert types(parser.parse_buffer(fast[2][0])) == ["SET_ACTUATOR_CONTROL_TARGET", "TIMESYNC"]
    # both .tlogs hold the same frames (in and out)
    assert (tmp_path / "fast.tlog").stat().st_size == (tmp_path / "reference.tlog").stat().st_size


def test_io_choice_comes_from_the_environment_and_a_bad_value_is_one_line(monkeypatch):
    monkeypatch.delenv("MAVREG_IO", raising=False)
    assert io_impl() == "fast"
    monkeypatch.setenv("MAVREG_IO", "reference")
    assert io_impl() == "reference"
    monkeypatch.setenv("MAVREG_IO", "turbo")
    with pytest.raises(ValueError, match="MAVREG_IO='turbo'"):
        io_impl()
    assert FastLink is not MavlinkLink
