"""The emulator's receive path with signing and peer filtering: its real UDP link and autopilot,
in this process (no subprocess); the daemon is played by pymavlink's own signing."""
from __future__ import annotations

import os
import socket
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from firmware_sim.cli import build_engine, build_parser, main
from mavreg.transport.signing import now_ticks

KEY = bytes(range(7, 39))
ARM, FORCE = 400, 21196


@pytest.fixture
def key_file(tmp_path):
    p = tmp_path / "key"
    p.write_text(KEY.hex())
    os.chmod(p, 0o600)
    return p


class Station:
    """A UDP socket with a pymavlink codec: the daemon (signing with the key) or an attacker."""

    def __init__(self, port, sysid=1, compid=191, key=None):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.dest = ("127.0.0.1", port)
        self.mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        if key is not None:
            self.mav.signing.secret_key, self.mav.signing.sign_outgoing = key, True
            self.mav.signing.timestamp = now_ticks()
        self.addr = self.sock.getsockname()

    def frame(self, msg, v1=False) -> bytes:
        return msg.pack(self.mav, force_mavlink1=v1)

    def send(self, frame: bytes) -> None:
        self.sock.sendto(frame, self.dest)

    def close(self):
        self.sock.close()


def heartbeat():
    return mavlink2.MAVLink_heartbeat_message(18, 8, 0, 0, 4, 3)


def command(p1, p2=0.0):
    return mavlink2.MAVLink_command_long_message(1, 1, ARM, 0, p1, p2, 0, 0, 0, 0, 0)


def target(c=(1.0, 0.0, 1.0, 0.0)):
    return mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, list(c) + [0.0] * 4)


def forged(frame: bytes, ts: int) -> bytes:
    """``frame`` (signed) with another timestamp and the signature left as it was: not valid."""
    return frame[:-12] + ts.to_bytes(6, "little") + frame[-6:]


def engine_for(*extra):
    args = build_parser().parse_args(["--listen", "udpin:127.0.0.1:0", "--world", "ideal", "--quiet", *extra])
    engine, _ = build_engine(args)
    return engine


def deliver(engine, station, *frames):
    """Send ``frames`` (one datagram each) and let the emulator take them."""
    for f in frames:
        station.send(f)
    deadline = time.monotonic() + 2.0
    n0 = engine.link.bytes_in
    want = sum(len(f) for f in frames)
    while engine.link.bytes_in - n0 < want and time.monotonic() < deadline:
        engine.link.wait_readable(0.05)
        engine.poll()


def test_signed_link_takes_only_the_signed_peer(key_file):
    engine = engine_for("--signing-key", str(key_file))
    port = engine.link.port
    daemon = Station(port, key=KEY)
    thief = Station(port)                                  # knows the ids, not the key
    holder = Station(port, sysid=9, key=KEY)               # has the key, is not a peer system
    try:
        deliver(engine, thief, thief.frame(heartbeat()))
        assert engine.link.peers == []                     # an unsigned heartbeat teaches nothing
        hb = daemon.frame(heartbeat())
        deliver(engine, daemon, hb)
        assert engine.link.peers == [daemon.addr]
        # forged-future-timestamp attack on the daemon's own stream, then the usual attacks
        arm = daemon.frame(command(1))
        deliver(engine, thief, forged(arm, now_ticks() + 10**9), thief.frame(command(1)),
                thief.frame(command(1), v1=True), thief.frame(target()))
        assert not engine.ap.armed and engine.targets_received == 0
        deliver(engine, daemon, arm)                       # the genuine stream is not blocked
        assert engine.ap.armed
        deliver(engine, daemon, daemon.frame(command(0)))
        assert not engine.ap.armed
        deliver(engine, daemon, arm)                       # replayed from the peer's own address
        deliver(engine, thief, arm, hb)                    # and from elsewhere
        deliver(engine, holder, holder.frame(command(1)))  # a foreign system with the key
        thief_signed = Station(port, key=KEY)              # the key at another address: no command
        deliver(engine, thief_signed, thief_signed.frame(command(1)))
        assert not engine.ap.armed and engine.link.peers == [daemon.addr]
        d = engine.drops()
        assert d["bad_signature"] == 1 and d["unsigned"] == 4 and d["replayed"] == 3
        assert d["foreign_system"] == 1 and d["foreign_address"] == 1
        assert "unsigned=4" in engine.status_line()
        # MAVLink 1 frames switched nothing off: everything the vehicle sent is signed and verifies
        engine.begin_period()
        daemon.sock.settimeout(2.0)
        checker = mavlink2.MAVLink(None)
        checker.signing.secret_key = KEY
        frames = checker.parse_buffer(daemon.sock.recv(65535))
        assert frames and all(m._signed for m in frames)
    finally:
        for s in (daemon, thief, holder):
            s.close()
        engine.link.close()
    assert (key_file.parent / "key.firmware-sim-state.json").exists()


def test_unsigned_link_takes_commands_only_from_the_peer_address_and_ids():
    engine = engine_for()
    port = engine.link.port
    daemon, thief = Station(port), Station(port)
    other_system, other_component = Station(port, sysid=9), Station(port, compid=190)
    try:
        deliver(engine, thief, thief.frame(command(1)), thief.frame(target()))
        assert not engine.ap.armed and engine.link.peers == []        # no heartbeat, no peer
        deliver(engine, daemon, daemon.frame(heartbeat()))
        deliver(engine, thief, thief.frame(command(1)), thief.frame(target()))
        deliver(engine, other_system, other_system.frame(heartbeat()), other_system.frame(command(1)))
        deliver(engine, other_component, other_component.frame(heartbeat()))
        assert not engine.ap.armed and engine.targets_received == 0
        assert engine.link.peers == [daemon.addr]
        deliver(engine, daemon, daemon.frame(command(1)), daemon.frame(target((0.1,) * 4)))
        assert engine.ap.armed and engine.targets_received == 1     # the peer itself is heard
        d = engine.drops()
        assert d["foreign_address"] == 4 and d["foreign_system"] == 2 and d["foreign_component"] == 1
    finally:
        for s in (daemon, thief, other_system, other_component):
            s.close()
        engine.link.close()


def test_cli_refuses_a_readable_key_file(tmp_path, capsys):
    p = tmp_path / "key"
    p.write_text(KEY.hex())
    os.chmod(p, 0o640)
    assert main(["--listen", "udpin:127.0.0.1:0", "--quiet", "--signing-key", str(p)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "chmod 600" in err and KEY.hex() not in err
