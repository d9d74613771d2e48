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

from fuzz.frames import ALL_CLASSES, DAEMON_ACTS_ON, EXTREME_FLOATS, KINDS, draw, pack, random_message
from fuzz.strategies import message
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



@FUZZ
@given(st.data())
def test_extreme_values_of_the_messages_the_daemon_acts_on(data):
    cls = data.draw(st.sampled_from(DAEMON_ACTS_ON))
    msg = message(data, cls)
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


def test_extreme_state_in_flight_never_raises_nor_commands_non_finite():
    """In the air (the harness flight, climbing), 300 state samples with extreme fields
    (NaN, infinities, float32 limits), each at a newer time: the supervisor takes every one
    without an exception, a non-finite part is counted and makes no sample, every rotor
    command that still leaves is finite (a finite but absurd state is the envelope's to judge),
    and the motors are not stopped: found by this test, one absurd sample 21 km under the
    ground at 176 m/s read as an impact (forced disarm in the air); the monitor now judges a
    sample that contradicts the one before as a position jump (a recovery) first."""
    from mavreg.daemon.flight.phases import AIRBORNE
    from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run, wire

    veh = SimVehicle()
    sup = make_supervisor(FakePlan(length_m=3.0))
    run(sup, veh, 6.0)
    assert sup.phase in AIRBORNE and -veh.x[2] > 0.3                # climbing, in the air
    rng = random.Random(5)
    t_ms = veh.t_ms
    for _ in range(300):
        t_ms += 4
        q = [rng.choice(EXTREME_FLOATS) if rng.random() < 0.3 else v for v in (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)]
        p = [rng.choice(EXTREME_FLOATS) if rng.random() < 0.3 else v for v in (0.0, 0.0, -2.0, 0.0, 0.0, 0.0)]
        n0 = sup.assembler.counters.non_finite
        for m in (mavlink2.MAVLink_attitude_quaternion_message(t_ms, *q),
                  mavlink2.MAVLink_local_position_ned_message(t_ms, *p)):
            out = sup.handle(wire(m), t_ms / 1000.0)
            for o in out.messages:
                if o.get_type() == "SET_ACTUATOR_CONTROL_TARGET":
                    assert all(math.isfinite(c) for c in o.controls)
        bad = not all(math.isfinite(v) for v in q[:4] + q[4:] + p)
        if bad:
            assert sup.assembler.counters.non_finite > n0
        if sup.last_sample is not None:
            assert all(math.isfinite(v) for v in sup.last_sample.x.tolist())
    assert sup.phase != "terminate" and sup.failure is not None               # judged, motors on
