"""Inputs for the receive paths: random bytes, damaged frames, CRC-valid frames of every
message of the common dialect with random fields, and valid messages with extreme values.

Everything is drawn from a ``random.Random`` passed in, so a seed reproduces a frame.
The property tests (``tests/unit/test_fuzz_daemon.py``, ``tests/firmware_sim/test_fuzz_fsim.py``)
and the long run (``python -m fuzz``) share these generators.
"""
from __future__ import annotations

import math
import random
import struct

from pymavlink.dialects.v20 import common as mavlink2

__all__ = ["ALL_CLASSES", "DAEMON_ACTS_ON", "VEHICLE_ACTS_ON", "EXTREME_FLOATS", "layout", "random_message",
           "pack", "damaged", "random_bytes", "KINDS", "draw", "draw_frames", "aim"]

ALL_CLASSES = tuple(sorted(mavlink2.mavlink_map.values(), key=lambda c: c.id))
"""Every message class of the common dialect (pymavlink's ``mavlink_map``)."""

_BY_NAME = {c.msgname: c for c in ALL_CLASSES}
DAEMON_ACTS_ON = tuple(_BY_NAME[n] for n in (
    "HEARTBEAT", "ATTITUDE", "ATTITUDE_QUATERNION", "LOCAL_POSITION_NED", "TIMESYNC", "COMMAND_ACK",
    "ODOMETRY", "STATUSTEXT"))
"""What the daemon parses (state, status, clock, acks), and ODOMETRY/STATUSTEXT it must ignore."""
VEHICLE_ACTS_ON = tuple(_BY_NAME[n] for n in (
    "COMMAND_LONG", "SET_ACTUATOR_CONTROL_TARGET", "TIMESYNC", "HEARTBEAT", "COMMAND_INT",
    "SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET"))
"""What firmware_sim acts on (SET_ATTITUDE_TARGET: body rates and thrust from the offboard peer),
and the setpoint messages a PX4 would (firmware_sim refuses the global one)."""

EXTREME_FLOATS = (math.nan, -math.nan, math.inf, -math.inf, 3.4028235e38, -3.4028235e38, 1e30, -1e30,
                  1.4e-45, -0.0, 0.0, 1.0, -1.0, 0.5, 21196.0, 400.0, 176.0)
_INT_RANGES = {"int8_t": (-128, 127), "uint8_t": (0, 255), "int16_t": (-2 ** 15, 2 ** 15 - 1),
               "uint16_t": (0, 2 ** 16 - 1), "int32_t": (-2 ** 31, 2 ** 31 - 1), "uint32_t": (0, 2 ** 32 - 1),
               "int64_t": (-2 ** 63, 2 ** 63 - 1), "uint64_t": (0, 2 ** 64 - 1)}
_F32 = struct.Struct("<f")


def layout(cls) -> list:
    """``[(name, type, array length), ...]`` in the constructor's order."""
    wire_len = dict(zip(cls.ordered_fieldnames, cls.array_lengths))
    return [(n, t, wire_len[n]) for n, t in zip(cls.fieldnames, cls.fieldtypes)]


def _value(rng: random.Random, ftype: str, extreme: bool):
    if ftype in ("float", "double"):
        if extreme or rng.random() < 0.2:
            return rng.choice(EXTREME_FLOATS)
        if ftype == "float":                   # any float32 bit pattern (NaNs with payloads included)
            return _F32.unpack(rng.getrandbits(32).to_bytes(4, "little"))[0]
        return rng.uniform(-1e6, 1e6) * 10.0 ** rng.randint(-10, 10)
    lo, hi = _INT_RANGES[ftype]
    if extreme or rng.random() < 0.2:
        return rng.choice((lo, hi, 0, 1, min(hi, 255)))
    return rng.randint(lo, hi)


def random_message(rng: random.Random, cls=None, extreme: bool = False):
    """A message of ``cls`` (default: any of the dialect) with random field values;
    ``extreme``: every number from the extremes (NaN, infinities, range limits)."""
    cls = cls if cls is not None else rng.choice(ALL_CLASSES)
    values = []
    for _, ftype, n in layout(cls):
        if ftype == "char":
            values.append(bytes(rng.randrange(256) for _ in range(rng.randint(0, max(n, 1)))))
        elif n:
            values.append([_value(rng, ftype, extreme) for _ in range(n)])
        else:
            values.append(_value(rng, ftype, extreme))
    return cls(*values)


def pack(msg, system_id: int = 1, component_id: int = 1, seq: int = 0) -> bytes:
    """The MAVLink 2 frame of ``msg`` from (system_id, component_id), CRC valid."""
    mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
    mav.seq = seq
    return msg.pack(mav)


def damaged(rng: random.Random, frame: bytes) -> bytes:
    """``frame`` cut short, with bits flipped (anywhere, the header included), or both."""
    how = rng.randrange(3)
    data = bytearray(frame)
    if how in (0, 2) and data:
        data = data[:rng.randrange(len(data))]
    if how in (1, 2) and data:
        for _ in range(rng.randint(1, 8)):
            i = rng.randrange(len(data))
            data[i] ^= 1 << rng.randrange(8)
    return bytes(data)


def random_bytes(rng: random.Random, max_len: int = 300) -> bytes:
    """Random bytes, often starting with a MAVLink start byte (0xFD or 0xFE)."""
    data = bytes(rng.randrange(256) for _ in range(rng.randint(0, max_len)))
    if data and rng.random() < 0.5:
        data = bytes([rng.choice((0xFD, 0xFE))]) + data[1:]
    return data


_COMMANDS = (mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, mavlink2.MAV_CMD_DO_SET_MODE, mavlink2.MAV_CMD_NAV_LAND,
             mavlink2.MAV_CMD_REQUEST_MESSAGE)


def aim(rng: random.Random, msg) -> None:
    """Address ``msg`` to system 1 (component 1 or 0) and give a command the vehicle handles,
    so that random and extreme values reach the acceptance rules behind the address checks."""
    if hasattr(msg, "target_system"):
        msg.target_system = 1
    if hasattr(msg, "target_component"):
        msg.target_component = rng.choice((0, 1))
    if hasattr(msg, "command"):
        msg.command = rng.choice(_COMMANDS)
    if hasattr(msg, "group_mlx") and rng.random() < 0.7:
        msg.group_mlx = 0


KINDS = ("bytes", "damaged", "any_message", "acted_on", "extreme")


def draw_frames(rng: random.Random, kind: str, acts_on: tuple, system_id: int = 1,
                component_id: int = 1) -> list:
    """The frames of one datagram of ``kind`` (see :data:`KINDS`): 1-3 frames for the message
    kinds, one blob of random bytes for ``bytes``."""
    if kind == "bytes":
        return [random_bytes(rng)]
    frames = []
    for _ in range(rng.randint(1, 3)):
        cls = rng.choice(ALL_CLASSES) if kind in ("any_message", "damaged") else rng.choice(acts_on)
        sysid = system_id if rng.random() < 0.8 else rng.choice((0, 2, 255))
        compid = component_id if rng.random() < 0.8 else rng.randrange(256)
        msg = random_message(rng, cls, extreme=kind == "extreme")
        if kind in ("acted_on", "extreme") and rng.random() < 0.7:
            aim(rng, msg)
        f = pack(msg, sysid, compid, rng.randrange(256))
        frames.append(damaged(rng, f) if kind == "damaged" else f)
    return frames


def draw(rng: random.Random, kind: str, acts_on: tuple, system_id: int = 1, component_id: int = 1) -> bytes:
    """One datagram of ``kind``: :func:`draw_frames` joined."""
    return b"".join(draw_frames(rng, kind, acts_on, system_id, component_id))
