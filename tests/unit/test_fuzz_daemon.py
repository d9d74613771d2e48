"""Fuzzing the daemon's receive path (link parsing + supervisor ingestion), seeded and bounded.

Each input goes through :class:`fuzz.targets.DaemonTarget`, whose ``feed`` returns the
findings: an exception that escaped, a stall, a state change that no valid message
explains, a non-finite state sample, or a non-finite state part that was not dropped and
counted. Hypothesis runs derandomized (the same examples every run)."""
from __future__ import annotations

import math
import random

from hypothesis import HealthCheck, given, settings, strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from fuzz.frames import ALL_CLASSES, DAEMON_ACTS_ON, EXTREME_FLOATS, KINDS, draw, layout, pack, random_message
from fuzz.targets import DaemonTarget

FUZZ = settings(max_examples=200, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
FAST, REFERENCE = DaemonTarget("fast"), DaemonTarget("reference")


@FUZZ
@given(st.binary(max_size=600))
def test_random_bytes(data):
    assert FAST.feed(data) == []
    assert REFERENCE.feed(data) == []


@FUZZ
@given(st.integers(0, 2 ** 64 - 1), st.sampled_from(KINDS))
def test_damaged_random_and_extreme_frames(seed, kind):
    data = draw(random.Random(seed), kind, DAEMON_ACTS_ON)
    assert FAST.feed(data) == []
    assert REFERENCE.feed(data) == []


def _field(ftype: str, n: int):
    if ftype == "char":
        return st.binary(max_size=max(n, 1))
    if ftype in ("float", "double"):
        one = st.one_of(st.sampled_from(EXTREME_FLOATS), st.floats(width=32 if ftype == "float" else 64))
    else:
        bits = int("".join(c for c in ftype if c.isdigit()))
        lo, hi = (0, 2 ** bits - 1) if ftype.startswith("u") else (-2 ** (bits - 1), 2 ** (bits - 1) - 1)
        one = st.integers(lo, hi)
    return st.lists(one, min_size=n, max_size=n) if n else one


@FUZZ
@given(st.data())
def test_extreme_values_of_the_messages_the_daemon_acts_on(data):
    cls = data.draw(st.sampled_from(DAEMON_ACTS_ON))
    msg = cls(*[data.draw(_field(t, n)) for _, t, n in layout(cls)])
    frame = pack(msg, 1, 1)
    assert FAST.feed(frame) == []
    assert REFERENCE.feed(frame) == []


def test_every_message_id_of_the_dialect_with_random_fields():
    rng = random.Random(21)
    target = DaemonTarget("fast")
    for cls in ALL_CLASSES:
        for extreme in (False, True, False):
            assert target.feed(pack(random_message(rng, cls, extreme), 1, 1)) == [], cls.msgname
    assert target.frames == 3 * len(ALL_CLASSES) == 630


def test_nan_attitude_is_dropped_counted_and_never_a_state():
    t = DaemonTarget("fast")
    pos = mavlink2.MAVLink_local_position_ned_message(100, 1.0, 2.0, -3.0, 0.0, 0.0, 0.0)
    for bad in ((math.nan, 0.0, 0.0, 0.0), (math.inf, 0.0, 0.0, 0.0), (1.0, 0.0, 0.0, -math.inf)):
        q = mavlink2.MAVLink_attitude_quaternion_message(100, *bad, 0.0, 0.0, 0.0)
        assert t.feed(pack(pos, 1, 1) + pack(q, 1, 1)) == []
        assert t.sup.last_sample is None
    assert t.sup.assembler.counters.non_finite == 3
    good = mavlink2.MAVLink_attitude_quaternion_message(100, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert t.feed(pack(good, 1, 1)) == []
    assert t.sup.last_sample.time_boot_ms == 100 and t.sup.last_sample.position_ned == (1.0, 2.0, -3.0)


def test_the_checks_see_a_state_change_without_a_valid_message():
    """Negative control of the harness: a sample slipped in behind the link's back is reported."""
    t = DaemonTarget("fast")
    t.passed = []
    before = t.snapshot()
    t.sup.assembler._pos[5] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert t.snapshot() != before
    orig = t.link.datagram_received

    def sneaky(data, addr):
        t.sup.assembler._pos[7] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        return orig(data, addr)

    t.link.datagram_received = sneaky
    found = t.feed(b"\x00garbage")
    assert found and found[0].startswith("state_change")
