"""The serial and TCP links over a real pseudo-terminal and loopback TCP: the daemon's and the
emulator's ends, a line nobody reads, a cable pulled, and bad devices in one line."""
from __future__ import annotations

import asyncio
import os
import socket
import subprocess
import sys

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim.link import open_link as open_emulator_link
from mavreg.daemon.vehicle.link import open_link
from mavreg.transport.tty import ByteStream, open_pty, open_serial
from tests.helpers.repo import ROOT as REPO

VEHICLE = mavlink2.MAVLink(None, srcSystem=3, srcComponent=1)
HEARTBEAT = mavlink2.MAVLink_heartbeat_message(2, 12, 129, 393216, 4, 3)


def _bundle(k: int) -> bytes:
    return b"".join(m.pack(VEHICLE) for m in (
        mavlink2.MAVLink_attitude_quaternion_message(k, 1, 0, 0, 0, 0, 0, 0, [0, 0, 0, 0]),
        mavlink2.MAVLink_local_position_ned_message(k, 1, 2, -3, 0, 0, 0)))


async def _until(condition, timeout_s: float = 5.0) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not condition():
        assert loop.time() < deadline, f"not within {timeout_s} s"
        await asyncio.sleep(0.001)


def _read_all(fd: int, wanted: int, timeout_s: float = 5.0) -> list:
    """Frames read from ``fd`` until ``wanted`` of them came."""
    import select
    parser = mavlink2.MAVLink(None)
    got = []
    while len(got) < wanted:
        r, _, _ = select.select([fd], [], [], timeout_s)
        assert r, f"only {len(got)} of {wanted} frames"
        got.extend(parser.parse_buffer(os.read(fd, 4096)) or [])
    return got


def test_the_daemon_takes_frames_cut_anywhere_learns_the_system_id_and_answers_on_the_line(tmp_path):
    master, slave, path = open_pty()
    closed = []

    async def run():
        got = []
        link = await open_link(f"serial:{path}:921600", None, 1, lambda m, t: got.append(m), None,
                               on_closed=closed.append)
        try:
            assert not link.send(HEARTBEAT)                   # nothing before the vehicle is heard
            data = HEARTBEAT.pack(VEHICLE) + b"\x00noise\xfd" + _bundle(1) + _bundle(2)
            for i in range(0, len(data), 7):                  # 7-byte reads: frames cut everywhere
                os.write(master, data[i:i + 7])
                await asyncio.sleep(0.0005)
            await asyncio.wait_for(link.connected.wait(), 2.0)
            await _until(lambda: len(got) == 5)
            assert link.system_id == 3 and link.counters.garbage_bytes == 7 and link.counters.bad_data >= 1
            cmd = mavlink2.MAVLink_set_actuator_control_target_message(5, 0, 3, 1, [0.3] * 4 + [0] * 4)
            assert link.send_many([cmd, mavlink2.MAVLink_timesync_message(0, 1234)])
            frames = _read_all(master, 2)
            assert [f.get_type() for f in frames] == ["SET_ACTUATOR_CONTROL_TARGET", "TIMESYNC"]
            assert frames[0].get_srcSystem() == 3 and frames[0].get_srcComponent() == 191
            os.close(master)                                  # the cable pulled
            os.close(slave)
            await _until(lambda: closed)
            assert "no more telemetry" in closed[0] and path in closed[0]
            assert not link.send(cmd)
        finally:
            link.close()
    asyncio.run(run())


def test_a_line_nobody_reads_drops_whole_writes_instead_of_queueing_stale_telemetry():
    master, slave, path = open_pty()
    stream = ByteStream(master, "pty", keep=(slave,))
    try:
        chunk = _bundle(0) * 20
        results = [stream.write(chunk) for _ in range(2000)]
        assert results[0] and not all(results) and stream.dropped_bytes > 0
        dropped = stream.dropped_bytes
        assert dropped % len(chunk) == 0          # whole writes dropped, never a frame cut short
    finally:
        stream.close()


def test_the_emulator_listens_on_a_pty_and_sends_first(tmp_path):
    link = open_emulator_link("pty", 1, 1)
    try:
        assert link.url.startswith("serial:/dev/") and link.peers           # sent to from the start
        fd = open_serial(link.url.split(":", 1)[1], 921600)
        try:
            link.send([HEARTBEAT])
            assert _read_all(fd, 1)[0].get_type() == "HEARTBEAT"
            daemon = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
            data = HEARTBEAT.pack(daemon) + b"\xfd\x09junk" + mavlink2.MAVLink_command_long_message(
                1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0).pack(daemon)
            os.write(fd, data[:9])
            assert link.wait_readable(2.0)
            first = link.recv_datagram()
            os.write(fd, data[9:])
            assert link.wait_readable(2.0)
            second = link.recv_datagram()
            types = [m.get_type() for m in first[0] + second[0]]
            assert types.count("HEARTBEAT") == 1 and types.count("COMMAND_LONG") == 1 and "BAD_DATA" in types
        finally:
            os.close(fd)
    finally:
        link.close()


def test_the_daemon_connects_over_tcp_to_the_emulator_as_a_server():
    server = open_emulator_link("tcpin:127.0.0.1:0", 1, 1)
    port = int(server.url.rsplit(":", 1)[1])

    async def run():
        got = []
        link = await open_link(f"tcp:127.0.0.1:{port}", None, 1, lambda m, t: got.append(m), None)
        try:
            for _ in range(200):
                server.recv_datagram()                          # accepts the client
                if server.peers:
                    break
                await asyncio.sleep(0.005)
            assert server.peers
            server.send([HEARTBEAT, mavlink2.MAVLink_local_position_ned_message(5, 1, 2, -3, 0, 0, 0)])
            await _until(lambda: len(got) == 2)
            assert link.system_id == 1 and got[1].get_type() == "LOCAL_POSITION_NED"
        finally:
            link.close()
        for _ in range(200):                                    # the client gone: listening again
            server.recv_datagram()
            if not server.peers:
                break
            await asyncio.sleep(0.005)
        assert not server.peers
    try:
        asyncio.run(run())
    finally:
        server.close()


def test_nobody_listening_on_tcp_is_one_line():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()

    async def run():
        await open_link(f"tcp:127.0.0.1:{port}", None, 1, lambda m, t: None, None)
    with pytest.raises(OSError) as err:
        asyncio.run(run())
    assert err.value.strerror.startswith(f"tcp 127.0.0.1:{port}: ")


def test_bad_devices_and_urls_are_one_line_and_exit_2_before_anything_starts(tmp_path):
    with pytest.raises(OSError) as err:
        open_serial("/dev/nonexistent-tty", 921600)
    assert err.value.strerror == "serial port /dev/nonexistent-tty: No such file or directory"
    plain = tmp_path / "plain"
    plain.write_text("x")
    with pytest.raises(OSError, match="not a terminal device"):
        open_serial(str(plain), 921600)
    master, slave, path = open_pty()
    try:
        with pytest.raises(OSError, match="baud 12345 cannot be set"):
            open_serial(path, 12345)
        env = {**os.environ, "PYTHONPATH": str(REPO)}
        hop = REPO / "tests/sitl/signing_hop.yaml"
        for args, needle in (
                (["mavreg.cli.main", "fly", str(hop), "--vehicle", f"serial:{path}:57600", "--control-rate-hz",
                  "200", "--out", str(tmp_path / "o")], "57600 baud is too slow for 200 Hz"),
                (["mavreg.cli.main", "fly", str(hop), "--vehicle", "serial:/dev/nonexistent-tty"],
                 "no device /dev/nonexistent-tty"),
                (["mavreg.cli.main", "serve", "--vehicle", "serial:dev/ttyACM0"], "absolute device path"),
                (["firmware_sim", "--listen", "serial:/dev/nonexistent-tty", "--quiet"], "No such file"),
                (["firmware_sim", "--listen", "tcpout:1:2"], "udpin:HOST:PORT, pty, serial:PATH[:BAUD] or tcpin"),
                (["firmware_sim", "--serial-byte-loss", "0.1", "--listen", "udpin:127.0.0.1:0"],
                 "--serial-byte-loss applies to a pty, serial or tcpin --listen")):
            p = subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, timeout=120,
                               cwd=REPO, env=env)
            lines = p.stderr.strip().splitlines()
            assert p.returncode == 2 and len(lines) == 1 and needle in lines[0], (args, p.stderr)
    finally:
        os.close(master)
        os.close(slave)
