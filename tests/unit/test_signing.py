"""MAVLink 2 signing (mavreg.transport.signing, .peers): sans-I/O, no sockets.

The verifier tests run on the emulator's own implementation too (mavreg.transport.signing, which
shares no code with mavreg's), with frames signed by the daemon's signer and by pymavlink."""
from __future__ import annotations

import os

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.paths import maneuver_file
from mavreg.transport import signing as sg
from mavreg.daemon.vehicle.peers import PeerFilter
from mavreg.daemon.logs.tlog import TlogWriter
from mavreg.transport.wire import Wire

KEY = bytes(range(1, 33))
T0 = 10**13                     # a signing timestamp (10 µs units since 2015)
VEHICLE = ("127.0.0.1", 14540)


def hb():
    return mavlink2.MAVLink_heartbeat_message(2, 12, 129, 0, 4, 3)


def disarm():
    return mavlink2.MAVLink_command_long_message(1, 1, 400, 0, 0, 21196, 0, 0, 0, 0, 0)


def signed(msg, ts, sysid=1, compid=1, key=KEY, link_id=0):
    """``msg`` from (sysid, compid), signed with ``key`` at timestamp ``ts``."""
    return sg.Signer(key, lambda: 0, ts - 1, link_id).sign(Wire(sysid, compid).pack(msg))


def forged(msg, ts, sysid=1, compid=1):
    """A frame that looks signed (flag, CRC, timestamp ``ts``) with a signature made without the key."""
    return signed(msg, ts, sysid, compid, key=os.urandom(32))


@pytest.fixture
def mod():
    """The signing module (the daemon's and the emulator's: one implementation)."""
    return sg


def write_key(path, text, mode=0o600):
    path.write_text(text)
    os.chmod(path, mode)
    return path


def test_good_signature_accepted_and_pymavlink_agrees(mod):
    v = mod.Verifier(KEY, T0)
    frame = signed(hb(), T0 + 5)
    assert v.check(frame) is None and v.streams[(0, 1, 1)] == T0 + 5
    other = mavlink2.MAVLink(None)           # an independent implementation checks our signature
    other.signing.secret_key = KEY
    assert other.parse_buffer(frame)[0]._signed
    # and we check pymavlink's
    src = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    src.signing.secret_key, src.signing.sign_outgoing, src.signing.timestamp = KEY, True, T0 + 9
    assert v.check(disarm().pack(src)) is None


def test_unsigned_and_badly_signed_dropped_and_counted_radio_status_allowed(tmp_path, mod):
    s = mod.Signing(write_key(tmp_path / "k", KEY.hex()), "t")
    unsigned = Wire(1, 1).pack(disarm())
    assert s.check(unsigned) == "unsigned"
    bad = bytearray(signed(disarm(), s.verifier.newest_ticks + 1))
    bad[-1] ^= 1
    assert s.check(bytes(bad)) == "bad_signature"
    assert s.check(forged(disarm(), s.verifier.newest_ticks + 2)) == "bad_signature"
    v1 = disarm().pack(mavlink2.MAVLink(None, srcSystem=1, srcComponent=1), force_mavlink1=True)
    assert s.check(v1) == "unsigned"
    radio = mavlink2.MAVLink_radio_status_message(200, 190, 90, 80, 70, 0, 0)
    assert s.check(Wire(51, 68).pack(radio)) is None                    # radios cannot sign
    assert s.drops == {"unsigned": 2, "bad_signature": 2, "replayed": 0} and s.accepted == 1


def test_replay_of_a_captured_frame_dropped(mod):
    v = mod.Verifier(KEY, T0)
    first, second = signed(hb(), T0 + 1), signed(disarm(), T0 + 2)
    assert v.check(first) is None and v.check(second) is None
    assert v.check(second) == "replayed" and v.check(first) == "replayed"
    assert v.check(signed(hb(), T0 + 3)) is None


def test_forged_future_timestamp_does_not_block_the_genuine_stream(mod):
    attack = forged(disarm(), T0 + 10**9)          # about three hours ahead, wrong signature
    genuine = signed(hb(), T0 + 1)
    v = mod.Verifier(KEY, T0)
    assert v.check(attack) == "bad_signature"
    assert (0, 1, 1) not in v.streams
    assert v.check(genuine) is None                 # the stream is not blocked
    # negative control: pymavlink 2.4's own check stores the forged timestamp first
    mav = mavlink2.MAVLink(None)
    mav.robust_parsing = True
    mav.signing.secret_key, mav.signing.timestamp = KEY, T0
    assert mav.parse_buffer(attack)[0].get_type() == "BAD_DATA"
    assert mav.signing.stream_timestamps[(0, 1, 1)] == T0 + 10**9
    assert mav.parse_buffer(genuine)[0].get_type() == "BAD_DATA"       # blocked for three hours


def test_new_stream_more_than_a_minute_old_rejected(mod):
    v = mod.Verifier(KEY, T0)
    minute = 60 * sg.TICKS_PER_S
    assert v.check(signed(hb(), T0 - minute - 1, sysid=2)) == "replayed"
    assert v.check(signed(hb(), T0 - minute + 1, sysid=3)) is None       # within the minute
    assert v.check(signed(hb(), T0 + 100, sysid=4)) is None
    assert v.newest_ticks == T0 + 100


def test_stream_table_bounded_and_eviction_reopens_nothing(mod):
    v = mod.Verifier(KEY, T0)
    captured = signed(hb(), T0 + 1, sysid=1)
    assert v.check(captured) is None
    for k in range(100):
        assert v.check(signed(hb(), T0 + 10 + k, sysid=(k % 250) + 2, compid=k // 250 + 1)) is None
    assert len(v.streams) == sg.MAX_STREAMS and (0, 1, 1) not in v.streams
    assert v.check(captured) == "replayed"          # its stream was evicted: still no replay
    assert v.check(signed(hb(), T0 + 1000, sysid=1)) is None


def test_mavlink1_frame_cannot_switch_signing_off():
    s = sg.Verifier(KEY, T0)
    f = PeerFilter(1, 1, VEHICLE, signing=_Counting(s))
    v1 = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    for msg in (hb(), disarm()):
        assert f.admit(msg.pack(v1, force_mavlink1=True), VEHICLE) == "unsigned"
    assert f.admit(signed(hb(), T0 + 1), VEHICLE) is None            # signed frames still taken
    out = sg.Signer(KEY, lambda: T0).sign(Wire(1, 191).pack(disarm()))
    assert out[2] & 1 and len(out) == len(Wire(1, 191).pack(disarm())) + 13     # and we still sign


class _Counting:
    """A Signing stand-in around a bare Verifier (PeerFilter calls ``check``)."""

    def __init__(self, verifier):
        self.check = verifier.check


def test_timestamp_persisted_and_a_restart_refuses_earlier_frames(tmp_path, mod):
    key = write_key(tmp_path / "key", KEY.hex())
    wall = [1.7e9]
    a = mod.Signing(key, "mavreg", wall_s=lambda: wall[0])
    t = a.verifier.newest_ticks
    captured = [signed(hb(), t + k) for k in range(1, 4)]
    assert [a.check(f) for f in captured] == [None] * 3
    sent = a.sign(Wire(1, 191).pack(hb()))
    a.save()
    state = (tmp_path / "key.mavreg-state.json")
    assert oct(state.stat().st_mode & 0o777) == "0o600" and KEY.hex() not in state.read_text()
    wall[0] -= 3600                                  # restarted with a clock an hour behind
    b = mod.Signing(key, "mavreg", wall_s=lambda: wall[0])
    assert [b.check(f) for f in captured] == ["replayed"] * 3
    assert b.signer.timestamp >= int.from_bytes(sent[-12:-6], "little")   # never reuses a timestamp
    assert b.check(signed(hb(), t + 10)) is None
    # without the state file the same restart would take the captured frames back (negative control)
    state.unlink()
    c = mod.Signing(key, "mavreg", wall_s=lambda: wall[0])
    assert c.check(captured[-1]) is None


def test_key_file_rules(tmp_path, mod):
    assert mod.load_key(write_key(tmp_path / "hex", KEY.hex() + "\n")) == KEY
    import base64
    assert mod.load_key(write_key(tmp_path / "b64", base64.b64encode(KEY).decode())) == KEY
    secret = KEY.hex()
    for name, text, mode, match in (("open", secret, 0o644, "group or others"),
                                    ("gw", secret, 0o620, "group or others"),
                                    ("short", secret[:-2], 0o600, "expected 32 bytes"),
                                    ("junk", "not a key at all", 0o600, "expected 32 bytes"),
                                    ("zero", "00" * 32, 0o600, "all-zero")):
        with pytest.raises(ValueError, match=match) as exc:
            mod.load_key(write_key(tmp_path / name, text, mode))
        assert secret not in str(exc.value) and "\n" not in str(exc.value)
    with pytest.raises(ValueError, match="signing key"):
        mod.load_key(tmp_path / "missing")


def test_fly_and_serve_refuse_a_readable_key_file_in_one_line(tmp_path, capsys):
    from mavreg.cli.main import main
    key = write_key(tmp_path / "key", KEY.hex(), 0o644)
    maneuver = maneuver_file("barrel_roll")
    for argv in (["fly", str(maneuver), "--out", str(tmp_path / "out")],
                 ["serve", "--socket", str(tmp_path / "s.sock")]):
        assert main([*argv, "--signing-key", str(key)]) == 2
        out, err = capsys.readouterr()
        assert err.count("\n") == 1 and "chmod 600" in err and KEY.hex() not in err + out, err
    assert not (tmp_path / "out").exists() and not (tmp_path / "s.sock").exists()


def test_peer_filter_daemon_side():
    s = sg.Verifier(KEY, T0)
    f = PeerFilter(1, 1, None, signing=_Counting(s))           # udpin: the address is learned
    stranger = ("10.0.0.9", 5000)
    assert f.admit(signed(disarm(), T0 + 1), VEHICLE) == "foreign_address"   # nothing before a HEARTBEAT
    assert f.admit(Wire(1, 1).pack(hb()), stranger) == "unsigned"           # cannot teach its address
    assert f.admit(signed(hb(), T0 + 2, sysid=7), stranger) == "foreign_system"
    assert f.addr is None
    assert f.admit(signed(hb(), T0 + 3), VEHICLE) is None and f.addr == VEHICLE
    assert f.admit(signed(disarm(), T0 + 4), stranger) == "foreign_address"
    assert f.admit(signed(disarm(), T0 + 5, compid=191), VEHICLE) == "foreign_system"
    setup = mavlink2.MAVLink_setup_signing_message(1, 1, bytes(32), 0)
    assert f.admit(signed(setup, T0 + 6), VEHICLE) == "setup_signing"


def test_tlog_never_holds_setup_signing(tmp_path):
    setup = Wire(1, 1).pack(mavlink2.MAVLink_setup_signing_message(1, 1, KEY, T0))
    with TlogWriter(tmp_path / "t.tlog") as w:
        w.write(setup)
        w.write_many([Wire(1, 1).pack(hb()), setup])
    data = (tmp_path / "t.tlog").read_bytes()
    assert w.count == 1 and KEY not in data and len(data) == 8 + len(Wire(1, 1).pack(hb()))


@pytest.mark.parametrize("impl", ["fast", "reference"])
def test_both_links_take_only_signed_vehicle_frames_and_sign_what_they_send(tmp_path, impl):
    """The links' receive path (fed directly, no socket) and send path with signing on."""
    from mavreg.daemon.vehicle.link import FastLink
    from mavreg.daemon.vehicle.link_reference import MavlinkLink
    signing = sg.Signing(write_key(tmp_path / "key", KEY.hex()), "t")
    got, sent = [], []
    tlog = TlogWriter(tmp_path / "t.tlog")
    if impl == "fast":
        sock = type("S", (), {"sendto": lambda self, d, a: sent.append(bytes(d)), "close": lambda self: None})()
        link = FastLink("udpin", None, 1, 1, lambda m, t: got.append(m), tlog, sock, signing)
    else:
        link = MavlinkLink("udpin", None, 1, 1, lambda m, t: got.append(m), tlog, signing=signing)
        link.transport = type("T", (), {"sendto": lambda self, d, a: sent.append(bytes(d)),
                                        "is_closing": lambda self: False, "close": lambda self: None})()
    t = signing.verifier.newest_ticks
    quat = mavlink2.MAVLink_attitude_quaternion_message(10, 1, 0, 0, 0, 0, 0, 0, [0, 0, 0, 0])
    link.datagram_received(Wire(1, 1).pack(quat), VEHICLE)                     # unsigned
    link.datagram_received(forged(hb(), t + 10**9), VEHICLE)                   # forged
    link.datagram_received(signed(hb(), t + 1) + signed(quat, t + 2), VEHICLE)
    link.datagram_received(signed(quat, t + 3), ("10.0.0.9", 5000))           # not the vehicle's address
    link.datagram_received(signed(quat, t + 2), VEHICLE)                       # replayed
    assert [m.get_type() for m in got] == ["HEARTBEAT", "ATTITUDE_QUATERNION"]
    c = link.counters
    assert (c.unsigned, c.bad_signature, c.replayed, c.foreign_address) == (1, 1, 1, 1)
    assert link.send(disarm())
    assert sent[0][2] & 1
    other = mavlink2.MAVLink(None)
    other.signing.secret_key = KEY
    assert other.parse_buffer(sent[0])[0]._signed               # pymavlink verifies what we sent
    link.close()
    tlog.close()
