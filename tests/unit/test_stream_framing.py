"""The byte-stream parts of the serial and TCP links, sans I/O: the frame splitter, the URLs,
and the line budget that refuses a baud too slow for the streams (analytic numbers)."""
from __future__ import annotations

import random

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.vehicle.link_budget import LINE_SHARE, baud_refusal, frame_bytes, link_budget
from mavreg.daemon.vehicle.peers import system_id_to_use
from mavreg.daemon.vehicle.url import parse_url
from mavreg.transport.wire import Wire
from mavreg.transport.framing import StreamFramer
from mavreg.transport.urls import DEFAULT_BAUD, parse_stream_url

VEHICLE = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)


def _stream(periods: int = 20) -> tuple[bytes, list[bytes]]:
    """A vehicle's bytes: a HEARTBEAT, then periods of ATTITUDE_QUATERNION + LOCAL_POSITION_NED
    and a STATUSTEXT (one frame the fast codec does not decode); and the frames one by one."""
    frames = [mavlink2.MAVLink_heartbeat_message(2, 12, 129, 393216, 4, 3).pack(VEHICLE)]
    for k in range(periods):
        frames.append(mavlink2.MAVLink_attitude_quaternion_message(2 * k, 1, 0, 0, 0, 0.1, 0, 0,
                                                                   [0, 0, 0, 0]).pack(VEHICLE))
        frames.append(mavlink2.MAVLink_local_position_ned_message(2 * k, 1.0 * k, 2, -3, 0, 0, 0).pack(VEHICLE))
    frames.append(mavlink2.MAVLink_statustext_message(4, b"mode HOLD", 0, 0).pack(VEHICLE))
    return b"".join(frames), frames


def _feed_in_pieces(framer: StreamFramer, data: bytes, sizes) -> bytes:
    out, i = [], 0
    for n in sizes:
        out.append(framer.feed(data[i:i + n]))
        i += n
    out.append(framer.feed(data[i:]))
    return b"".join(out)


def test_frames_split_across_reads_come_out_whole_at_every_cut():
    data, frames = _stream(3)
    for cut in range(1, len(data)):                  # two reads, cut at every byte
        framer = StreamFramer()
        assert _feed_in_pieces(framer, data, [cut]) == data
        assert framer.counters.frames == len(frames) and framer.counters.garbage_bytes == 0
    framer = StreamFramer()
    assert _feed_in_pieces(framer, data, [1] * len(data)) == data      # a byte at a time
    assert framer.pending_bytes == 0


def test_garbage_between_frames_is_skipped_and_counted_and_the_codec_decodes_the_rest():
    data, frames = _stream(5)
    noise = b"\x00\xfd\x05\xfe\x01garbage\xfd"       # start bytes inside the noise too
    framer = StreamFramer()
    out = framer.feed(frames[0] + noise + b"".join(frames[1:]))
    assert out == data and framer.counters.frames == len(frames)
    assert framer.counters.garbage_bytes == len(noise) and framer.counters.bad_frames >= 3
    msgs = Wire(1, 191).parse(out)
    assert [m.get_type() for m in msgs].count("LOCAL_POSITION_NED") == 5 and msgs[-1].get_type() == "STATUSTEXT"


def test_a_lost_or_corrupted_byte_costs_its_frame_only():
    data, frames = _stream(4)
    for k in (1, 2, 5):
        lost = bytearray(frames[k])
        del lost[7 + k]                                  # a byte lost on the line
        framer = StreamFramer()
        got = framer.feed(b"".join(frames[:k]) + bytes(lost) + b"".join(frames[k + 1:]))
        assert got == b"".join(frames[:k] + frames[k + 1:]), k
        flipped = bytearray(frames[k])
        flipped[12] ^= 0x40                              # a byte corrupted on the line
        framer = StreamFramer()
        assert framer.feed(b"".join(frames[:k]) + bytes(flipped) + b"".join(frames[k + 1:])) == got


def test_random_bytes_and_random_damage_never_crash_and_every_frame_out_is_valid():
    rng = random.Random(7)
    data, frames = _stream(40)
    for trial in range(200):
        line = bytearray(data)
        for _ in range(rng.randrange(0, 12)):
            i = rng.randrange(len(line))
            action = rng.randrange(3)
            if action == 0:
                del line[i]
            elif action == 1:
                line[i] = rng.randrange(256)
            else:
                line[i:i] = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 30)))
        framer = StreamFramer()
        sizes = [rng.randrange(1, 200) for _ in range(40)]
        out = _feed_in_pieces(framer, bytes(line), sizes)
        parsed = mavlink2.MAVLink(None).parse_buffer(out) or []
        assert all(m.get_type() != "BAD_DATA" for m in parsed), trial
        assert len(parsed) == framer.counters.frames
    assert StreamFramer().feed(bytes(rng.randrange(256) for _ in range(5000))) is not None


def test_stream_urls_and_the_serial_default_baud():
    assert parse_stream_url("serial:/dev/ttyACM0:57600") == ("serial", "/dev/ttyACM0", 57600)
    assert parse_stream_url("serial:/dev/ttyACM0") == ("serial", "/dev/ttyACM0", DEFAULT_BAUD) \
        and DEFAULT_BAUD == 921600
    assert parse_url("tcp:127.0.0.1:5760") == ("tcp", "127.0.0.1", 5760)
    assert parse_url("udpout:127.0.0.1:14540") == ("udpout", "127.0.0.1", 14540)
    for bad, why in (("serial:ttyACM0", "absolute device path"), ("serial:/dev/ttyACM0:0", "positive"),
                     ("tcp:host", "tcp:HOST:PORT"), ("tcp:host:0", "out of range"), ("tcp:h:x", "not a number"),
                     ("tcpin:h:1", "serial:PATH[:BAUD]"), ("com3", "udpin:HOST:PORT")):
        with pytest.raises(ValueError, match="vehicle URL") as err:
            parse_url(bad)
        assert why in str(err.value) and "\n" not in str(err.value), bad
    # one peer by construction: the vehicle's system id comes from its first HEARTBEAT
    assert system_id_to_use("serial:/dev/ttyAMA0", None) is None and system_id_to_use("tcp:h:1", None) is None
    assert system_id_to_use("udpout:h:1", None) == 1 and system_id_to_use("serial:/dev/x", 6) == 6


def test_frame_sizes_and_the_budget_in_bytes_per_second_are_the_analytic_ones():
    # MAVLink 2: 10 header bytes + payload + 2 CRC (+ 13 signed)
    assert frame_bytes(mavlink2.MAVLINK_MSG_ID_ATTITUDE_QUATERNION) == 12 + 48
    assert frame_bytes(mavlink2.MAVLINK_MSG_ID_LOCAL_POSITION_NED) == 12 + 28
    assert frame_bytes(mavlink2.MAVLINK_MSG_ID_SET_ACTUATOR_CONTROL_TARGET, signed=True) == 12 + 43 + 13
    b = link_budget(200.0)
    # 200 Hz x (60 + 40) + EXTENDED_SYS_STATE 5 Hz x 14 + HEARTBEAT 1 Hz x 21 + TIMESYNC 10 Hz x 28
    assert b.down_bytes_per_s == pytest.approx(200 * 100 + 5 * 14 + 21 + 10 * 28) == 20371
    # 200 Hz x SET_ACTUATOR_CONTROL_TARGET 55 + TIMESYNC 10 Hz x 28 + HEARTBEAT 21
    assert b.up_bytes_per_s == pytest.approx(200 * 55 + 280 + 21)
    assert b.needed_baud_bps == pytest.approx(20371 * 10 / LINE_SHARE) == pytest.approx(254637.5)
    assert link_budget(200.0, "rates").up_bytes_per_s == pytest.approx(200 * (12 + 39) + 301)


def test_a_baud_too_slow_for_200_hz_is_refused_in_one_line_naming_the_baud_needed():
    why = baud_refusal(57600, 200.0, name="--vehicle serial:/dev/ttyS0:57600")
    assert why is not None and "\n" not in why
    assert "57600 baud is too slow for 200 Hz" in why and "254,638 baud" in why and "921600" in why
    # the highest rate that fits 57600: (57600 x 0.8 / 10 - 371) / 100 B per period = 42.37 Hz
    assert "--control-rate-hz to 42 or less" in why
    assert baud_refusal(230400, 200.0) is not None and baud_refusal(460800, 200.0) is None
    assert baud_refusal(921600, 500.0) is None and baud_refusal(921600, 1000.0) is not None
    assert baud_refusal(460800, 200.0, signed=True) is None


def test_a_line_that_loses_bytes_is_seeded_and_loses_the_share_asked_for():
    from mavreg.tools.faultlink import ByteLoss
    data, _ = _stream(400)
    a, b = ByteLoss(1e-3, seed=3), ByteLoss(1e-3, seed=3)
    pieces = [data[i:i + 97] for i in range(0, len(data), 97)]
    out_a = b"".join(a.apply(p) for p in pieces)
    assert out_a == b.apply(data)                      # the same bytes lost however the reads cut
    assert len(data) - len(out_a) == a.lost and a.bytes == len(data)
    assert 0.5e-3 < a.lost / len(data) < 2e-3
    framer = StreamFramer()
    framer.feed(out_a)
    assert 0 < framer.counters.bad_frames <= a.lost        # each lost byte costs at most its frame
    assert ByteLoss(0.0).apply(data) == data
    with pytest.raises(ValueError, match="byte loss"):
        ByteLoss(1.0)
