"""Fuzzing firmware_sim's receive path (socket, codec, engine, autopilot), seeded and bounded.

Each input is sent to a live :class:`firmware_sim.link.Link` on loopback and taken up by the
engine (:class:`fuzz.targets.VehicleTarget`); ``feed`` returns the findings: an exception
that escaped, a stall, arming or a mode change without an accepted command, or the
offboard peer or target changed without a valid target."""
from __future__ import annotations

import math
import random

from hypothesis import HealthCheck, given, settings, strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from fuzz.frames import ALL_CLASSES, KINDS, VEHICLE_ACTS_ON, aim, draw, pack, random_message
from fuzz.strategies import message
from fuzz.targets import VehicleTarget

FUZZ = settings(max_examples=200, derandomize=True, deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
VEHICLE = VehicleTarget()


@FUZZ
@given(st.binary(max_size=600))
def test_random_bytes(data):
    assert VEHICLE.feed(data) == []


@FUZZ
@given(st.integers(0, 2 ** 64 - 1), st.sampled_from(KINDS))
def test_damaged_random_and_extreme_frames(seed, kind):
    assert VEHICLE.feed(draw(random.Random(seed), kind, VEHICLE_ACTS_ON, 1, 191)) == []



@FUZZ
@given(st.data())
def test_extreme_values_of_the_messages_the_vehicle_acts_on(data):
    cls = data.draw(st.sampled_from(VEHICLE_ACTS_ON))
    msg = message(data, cls)
    if data.draw(st.booleans()):
        aim(random.Random(data.draw(st.integers(0, 2 ** 32))), msg)
    sysid = data.draw(st.sampled_from((1, 1, 255, 7)))
    assert VEHICLE.feed(pack(msg, sysid, 191)) == []


def test_every_message_id_of_the_dialect_with_random_fields():
    rng = random.Random(21)
    target = VehicleTarget()
    try:
        for cls in ALL_CLASSES:
            for extreme in (False, True):
                assert target.feed(pack(random_message(rng, cls, extreme), 1, 191)) == [], cls.msgname
    finally:
        target.close()


def _command(command, p1, p2=0.0, p3=0.0):
    return pack(mavlink2.MAVLink_command_long_message(1, 1, command, 0, p1, p2, p3, 0, 0, 0, 0), 1, 191)


def test_non_finite_command_parameters_are_denied_and_counted():
    """Found by fuzzing: DO_SET_MODE with a NaN parameter raised out of the receive path.
    ARM_DISARM's param2 (force) is not read to arm: NaN there is how MAVSDK sends an unused
    parameter, and it arms, as on PX4."""
    t = VehicleTarget()
    try:
        for cmd, args in ((176, (math.nan, 6.0)), (176, (1.0, math.inf)), (176, (1.0, 4.0, -math.inf)),
                          (400, (math.nan,)), (400, (math.inf, 0.0))):
            assert t.feed(_command(cmd, *args)) == []
        assert t.ap.drops["non_finite"] == 5 and not t.ap.armed
        assert t.feed(_command(400, 1.0, math.nan)) == [] and t.ap.armed   # a finite param1 arms
    finally:
        t.close()


def test_a_malformed_target_does_not_claim_the_offboard_peer():
    """Found by fuzzing: a non-finite target from component 77 made 77 the offboard peer, and
    the daemon's valid targets (component 191) were then dropped as foreign_component."""
    t = VehicleTarget()
    try:
        nan = pack(mavlink2.MAVLink_set_actuator_control_target_message(
            0, 0, 1, 1, [math.nan, 0.5, 0.5, 0.5, 0, 0, 0, 0]), 1, 77)
        big = pack(mavlink2.MAVLink_set_actuator_control_target_message(
            0, 0, 1, 1, [5.0, 0.5, 0.5, 0.5, 0, 0, 0, 0]), 1, 78)
        assert t.feed(nan) == [] and t.feed(big) == []
        assert t.ap.offboard_component is None
        good = pack(mavlink2.MAVLink_set_actuator_control_target_message(
            0, 0, 1, 1, [0.5, 0.5, 0.5, 0.5, 0, 0, 0, 0]), 1, 191)
        assert t.feed(good) == [] and t.ap.offboard_component == 191 and t.ap.target_count == 1
    finally:
        t.close()
