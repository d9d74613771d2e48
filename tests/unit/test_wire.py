"""The precompiled MAVLink codecs (the daemon's and the emulator's copy) agree with pymavlink's."""
from __future__ import annotations

import random
import struct

import pytest
from pymavlink.dialects.v20 import common as mavlink2

import mavreg.transport.wire

CODECS = pytest.mark.parametrize("wire_mod", [mavreg.transport.wire], ids=["wire"])


def _random_messages(rng: random.Random, n: int) -> list:
    f = lambda: struct.unpack("<f", struct.pack("<f", rng.uniform(-100, 100)))[0]  # noqa: E731
    out = []
    for _ in range(n):
        k = rng.randrange(9)
        zero = rng.random() < 0.2          # trailing zeros: MAVLink 2 truncates the payload
        if k == 0:
            out.append(mavlink2.MAVLink_attitude_message(rng.randrange(2**32), f(), f(), f(), f(), f(),
                                                         0.0 if zero else f()))
        elif k == 1:
            out.append(mavlink2.MAVLink_attitude_quaternion_message(
                rng.randrange(2**32), f(), f(), f(), f(), f(), f(), f(),
                [0.0] * 4 if zero else [f(), f(), f(), f()]))
        elif k == 2:
            out.append(mavlink2.MAVLink_local_position_ned_message(rng.randrange(2**32), f(), f(), f(), f(), f(),
                                                                   0.0 if zero else f()))
        elif k == 3:
            c = [rng.random() for _ in range(4)] + ([0.0] * 4 if zero else [f() for _ in range(4)])
            out.append(mavlink2.MAVLink_set_actuator_control_target_message(
                rng.randrange(2**63), 0, rng.randrange(256), 0 if zero else rng.randrange(256), c))
        elif k == 4:
            out.append(mavlink2.MAVLink_timesync_message(0 if zero else rng.randrange(-2**62, 2**62),
                                                         rng.randrange(-2**62, 2**62)))
        elif k == 5:
            out.append(mavlink2.MAVLink_heartbeat_message(2, 12, rng.randrange(256), rng.randrange(2**32), 4, 3))
        elif k == 6:
            out.append(mavlink2.MAVLink_command_ack_message(400, rng.randrange(6), 0, 0, 1, 0 if zero else 191))
        elif k == 7:
            out.append(mavlink2.MAVLink_command_long_message(1, 1, 176, 0, *[f() for _ in range(7)]))
        else:                               # no precompiled codec: pymavlink's path
            out.append(mavlink2.MAVLink_statustext_message(4, b"mode OFFBOARD: by command", 0, 0))
    return out


@CODECS
def test_pack_is_byte_identical_to_pymavlink_with_the_same_sequence(wire_mod):
    rng = random.Random(1)
    wire = wire_mod.Wire(1, 191)
    ref = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)
    msgs = _random_messages(rng, 600)                  # > 256: the sequence number wraps
    for m in msgs:
        expected = m.pack(ref)
        ref.seq = (ref.seq + 1) % 256
        assert wire.pack(m) == expected, m.get_type()


@CODECS
def test_parse_gives_the_same_messages_as_pymavlink(wire_mod):
    rng = random.Random(2)
    src = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    frames = []
    for m in _random_messages(rng, 400):
        frames.append(m.pack(src))
        src.seq = (src.seq + 1) % 256
    wire = wire_mod.Wire(1, 191)
    ref = mavlink2.MAVLink(None)
    ref.robust_parsing = True
    k = 0
    while k < len(frames):                             # datagrams of 1..4 frames
        n = rng.randint(1, 4)
        chunk = frames[k:k + n]
        k += n
        data = b"".join(chunk)
        got, want = wire.parse(data), ref.parse_buffer(data)
        assert len(got) == len(want) == len(chunk)
        for g, w in zip(got, want):
            assert type(g) is type(w)
            assert g == w                              # type, CRC, seq, ids, every field
            assert g.to_dict() == w.to_dict()
            assert bytes(g.get_msgbuf()) == bytes(w.get_msgbuf())
            assert bytes(g.get_payload()) == bytes(w.get_payload())
            h, r = g.get_header(), w.get_header()
            assert (h.msgId, h.mlen, h.seq, h.srcSystem, h.srcComponent, h.incompat_flags, h.compat_flags) == \
                (r.msgId, r.mlen, r.seq, r.srcSystem, r.srcComponent, r.incompat_flags, r.compat_flags)
    assert wire.fast_in > 300 and wire.slow_in > 0   # statustext went the reference way


@CODECS
@pytest.mark.parametrize("damage", ["crc", "truncate", "garbage_prefix", "garbage_suffix", "mavlink1", "empty"])
def test_damaged_datagrams_are_reported_as_pymavlink_reports_them(damage, wire_mod):
    src = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    good = [mavlink2.MAVLink_local_position_ned_message(10, 1, 2, 3, 4, 5, 6).pack(src),
            mavlink2.MAVLink_attitude_message(10, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6).pack(src)]
    data = b"".join(good)
    if damage == "crc":
        data = data[:20] + bytes([data[20] ^ 0xFF]) + data[21:]
    elif damage == "truncate":
        data = data[:-5]
    elif damage == "garbage_prefix":
        data = b"\x01\x02garbage" + data
    elif damage == "garbage_suffix":
        data = data + b"\xfd\x09zz"
    elif damage == "mavlink1":
        src1 = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        data = mavlink2.MAVLink_heartbeat_message(2, 12, 0, 0, 4, 3).pack(src1, force_mavlink1=True) + data
    elif damage == "empty":
        data = b""
    ref = mavlink2.MAVLink(None)
    ref.robust_parsing = True
    want = ref.parse_buffer(data) or []
    wire = wire_mod.Wire(1, 191)
    got = wire.parse(data)
    assert [m.get_type() for m in got] == [m.get_type() for m in want]
    for g, w in zip(got, want):
        if w.get_type() != "BAD_DATA":
            assert g == w
    # the next, clean datagram decodes the same way in both (a cut-short tail stays pending in both)
    more = mavlink2.MAVLink_timesync_message(0, 77).pack(src)
    assert [m.get_type() for m in wire.parse(more)] == [m.get_type() for m in (ref.parse_buffer(more) or [])]


@CODECS
def test_crc_matches_the_reference_algorithm_and_the_fast_path_is_detected(wire_mod):
    data = bytes(range(256)) * 3
    assert wire_mod.mcrf4xx(data) == wire_mod._slow_mcrf4xx(data) == mavlink2.x25crc(data).crc
    assert wire_mod.mcrf4xx(b"123456789") == 0x6F91                     # CRC-16/MCRF4XX check value
    assert wire_mod.crc_is_fast() == (wire_mod._fast_mcrf4xx is not None)


@CODECS
def test_the_hot_messages_have_precompiled_codecs(wire_mod):
    for m in ("HEARTBEAT", "ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "TIMESYNC",
              "SET_ACTUATOR_CONTROL_TARGET"):
        assert getattr(mavlink2, f"MAVLINK_MSG_ID_{m}") in wire_mod.FAST_IDS


def test_skipped_ids_come_back_as_their_wire_bytes_in_place():
    src = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    frames = [m.pack(src) for m in (mavlink2.MAVLink_attitude_message(1, 0.1, 0.2, 0.3, 0, 0, 0),
                                    mavlink2.MAVLink_local_position_ned_message(1, 1, 2, 3, 4, 5, 6),
                                    mavlink2.MAVLink_attitude_message(2, 0.1, 0.2, 0.3, 0, 0, 0))]
    got = mavreg.transport.wire.Wire(1, 191).parse(b"".join(frames), {mavlink2.MAVLINK_MSG_ID_ATTITUDE})
    assert got[0] == frames[0] and got[2] == frames[2] and got[1].get_type() == "LOCAL_POSITION_NED"
