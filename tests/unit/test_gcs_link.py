"""The ground-station UDP adapter over real loopback sockets (no flight, an injected clock)."""
from __future__ import annotations

import asyncio
import socket

from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.vehicle import messages as mm
from mavreg.daemon.gcs.bridge import GcsParams
from mavreg.daemon.gcs.link import GcsLink
from mavreg.daemon.flight.phases import Event, Output

VEHICLE = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
GCS = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)


class _Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def _decoded(msg):
    parser = mavlink2.MAVLink(None)
    return parser.parse_buffer(msg.pack(VEHICLE))[0]


def _recv_all(sock, timeout_s=2.0):
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    sock.settimeout(timeout_s)
    out = []
    try:
        while True:
            out.extend(parser.parse_buffer(sock.recv(65535)) or [])
            sock.settimeout(0.2)
    except (socket.timeout, BlockingIOError):
        pass
    return out


async def _session(allow: bool, in_control: bool):
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    port = gcs.getsockname()[1]
    stranger = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    clock = _Clock()
    to_vehicle, lands, lines = [], [], []
    link = GcsLink([f"udpout:127.0.0.1:{port}"], 1, GcsParams(allow_commands=allow), clock,
                   lambda: in_control, lambda m: to_vehicle.append(m) or True, lambda: lands.append(1),
                   lines.append)
    await link.open()
    try:
        link.vehicle_message(_decoded(mavlink2.MAVLink_heartbeat_message(2, 12, 129, 6 << 16, 4, 3)))
        link.heartbeat(mm.daemon_heartbeat(True), "takeoff")
        out = Output(events=[Event(1.0, "phase", "takeoff", float("nan"), "take-off from z=0.00 m")])
        link.daemon_output(out)
        got = await asyncio.to_thread(_recv_all, gcs)
        ours = link.endpoints[0].sock.getsockname()
        cmds = [mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3),
                mavlink2.MAVLink_command_long_message(1, 1, mavlink2.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0),
                mavlink2.MAVLink_command_long_message(1, 1, mavlink2.MAV_CMD_DO_SET_MODE, 0, 1, 4, 3, 0, 0, 0, 0),
                mavlink2.MAVLink_command_long_message(1, 1, mavlink2.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)]
        gcs.sendto(b"".join(m.pack(GCS) for m in cmds), ("127.0.0.1", ours[1]))
        gcs.sendto(b"\xfe\x01 not mavlink at all", ("127.0.0.1", ours[1]))
        stranger.sendto(cmds[1].pack(GCS), ("127.0.0.1", ours[1]))       # not the ground station
        for _ in range(20):
            await asyncio.sleep(0.01)
        replies = await asyncio.to_thread(_recv_all, gcs)
        return got, replies, to_vehicle, lands, link.status()[0], lines
    finally:
        await link.aclose()
        assert link._task.done()
        gcs.close()
        stranger.close()


def test_udpout_endpoint_sees_the_flight_and_is_read_only():
    got, replies, to_vehicle, lands, st, lines = asyncio.run(_session(allow=False, in_control=True))
    ids = [(m.get_type(), m.get_srcSystem(), m.get_srcComponent()) for m in got]
    assert ids == [("HEARTBEAT", 1, 1), ("HEARTBEAT", 1, 191), ("NAMED_VALUE_INT", 1, 191),
                   ("STATUSTEXT", 1, 191), ("NAMED_VALUE_INT", 1, 191)]
    assert got[3].text == "mavreg phase takeoff: take-off from z=0.00 m"
    assert to_vehicle == [] and lands == []
    assert st["from_gcs"] == 4 and st["dropped_never"] == 1 and st["dropped_read_only"] == 3
    assert st["bad_data"] >= 1 and st["foreign_address"] == 1 and st["to_gcs"] >= 4
    assert {m.get_type() for m in replies} == {"COMMAND_ACK", "STATUSTEXT"}
    assert "read-only" in lines[0]


def test_udpout_endpoint_with_commands_allowed():
    _, replies, to_vehicle, lands, st, _ = asyncio.run(_session(allow=True, in_control=True))
    assert [m.command for m in to_vehicle] == [mavlink2.MAV_CMD_REQUEST_MESSAGE]
    assert lands == [1]
    assert st["refused"] == 1 and st["to_vehicle"] == 1 and st["land_requests"] == 1
    denied = [m.command for m in replies if m.get_type() == "COMMAND_ACK"]
    assert denied == [mavlink2.MAV_CMD_DO_SET_MODE]


async def _udpin_session():
    clock = _Clock()
    link = GcsLink(["udpin:127.0.0.1:0"], 1, GcsParams(), clock, lambda: True, lambda m: True,
                   lambda: None, lambda line: None)
    await link.open()
    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        link.heartbeat(mm.daemon_heartbeat(True), "preflight")
        link.flush()                                   # nobody has spoken yet: dropped
        before = dict(link.status()[0])
        port = link.endpoints[0].sock.getsockname()[1]
        gcs.sendto(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(GCS), ("127.0.0.1", port))
        for _ in range(10):
            await asyncio.sleep(0.01)
        link.heartbeat(mm.daemon_heartbeat(True), "preflight")
        got = await asyncio.to_thread(_recv_all, gcs)
        return before, got
    finally:
        link.close()
        gcs.close()


def test_udpin_endpoint_answers_the_ground_station_that_spoke_first():
    before, got = asyncio.run(_udpin_session())
    assert before["dropped_queue"] == 2 and before["to_gcs"] == 0
    assert [m.get_type() for m in got] == ["HEARTBEAT", "NAMED_VALUE_INT"]


def test_an_endpoint_that_cannot_open_is_one_line():
    async def go(url):
        link = GcsLink([url], 1, GcsParams(), _Clock(), lambda: True, lambda m: True, lambda: None,
                       lambda line: None)
        await link.open()
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        for url in ("udpout:no-such-host.invalid:14550", f"udpin:127.0.0.1:{busy.getsockname()[1]}"):
            try:
                asyncio.run(go(url))
            except OSError as exc:
                assert str(exc).startswith(f"--gcs {url!r}: ") and "\n" not in str(exc)
            else:
                raise AssertionError(f"{url} opened")
    finally:
        busy.close()
