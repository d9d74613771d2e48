"""MAVLink message construction and decoding helpers for the daemon (no I/O).

Messages are pymavlink's generated MAVLink 2 classes of the common dialect; the link
packs them with its own :class:`MAVLink` instance (system and component id, sequence).
Flight modes use PX4's custom_mode encoding ``(main << 16) | (sub << 24)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

__all__ = ["mavlink2", "rate_target", "RATE_TYPE_MASK", "PX4_MAIN_OFFBOARD", "PX4_MAIN_AUTO", "PX4_SUB_LOITER", "PX4_SUB_LAND",
           "VehicleStatus", "decode_heartbeat", "actuator_target", "arm_disarm", "force_disarm",
           "set_offboard", "daemon_heartbeat", "mode_name", "statustext", "SEVERITY_CRITICAL",
           "SEVERITY_WARNING", "SEVERITY_INFO", "FORCE_DISARM_MAGIC"]

PX4_MAIN_AUTO = 4
PX4_MAIN_OFFBOARD = 6
PX4_SUB_LOITER = 3
PX4_SUB_LAND = 6
FORCE_DISARM_MAGIC = 21196.0
"""param2 of ARM_DISARM that forces a disarm in flight (PX4's value)."""
SEVERITY_CRITICAL = mavlink2.MAV_SEVERITY_CRITICAL
SEVERITY_WARNING = mavlink2.MAV_SEVERITY_WARNING
SEVERITY_INFO = mavlink2.MAV_SEVERITY_INFO
_TEXT_LEN = 50
_MAX_CHUNKS = 6


@dataclass(frozen=True)
class VehicleStatus:
    """What the vehicle's HEARTBEAT says."""

    armed: bool
    main_mode: int
    sub_mode: int
    system_status: int

    @property
    def offboard(self) -> bool:
        return self.main_mode == PX4_MAIN_OFFBOARD

    @property
    def mode(self) -> str:
        return mode_name(self.main_mode, self.sub_mode)


def mode_name(main: int, sub: int) -> str:
    """PX4-style name of a (main, sub) mode."""
    if main == PX4_MAIN_OFFBOARD:
        return "OFFBOARD"
    if main == PX4_MAIN_AUTO:
        return {PX4_SUB_LOITER: "AUTO.LOITER", PX4_SUB_LAND: "AUTO.LAND"}.get(sub, f"AUTO.{sub}")
    return f"MODE({main},{sub})"


def decode_heartbeat(msg) -> VehicleStatus:
    """Armed flag and PX4 mode of a vehicle HEARTBEAT."""
    cm = int(msg.custom_mode)
    return VehicleStatus(
        armed=bool(msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED),
        main_mode=(cm >> 16) & 0xFF,
        sub_mode=(cm >> 24) & 0xFF,
        system_status=int(msg.system_status),
    )


def actuator_target(time_usec: int, target_system: int, target_component: int, controls4) -> object:
    """SET_ACTUATOR_CONTROL_TARGET, group 0, controls[0..3] = rotors 1..4 in [0, 1].

    Raises ValueError on a non-finite or out-of-range value: such a message must never
    be built, let alone sent.
    """
    c = controls4.tolist() if isinstance(controls4, np.ndarray) else [float(v) for v in controls4]
    if len(c) != 4 or not (0.0 <= c[0] <= 1.0 and 0.0 <= c[1] <= 1.0 and 0.0 <= c[2] <= 1.0
                           and 0.0 <= c[3] <= 1.0):        # NaN fails every comparison
        raise ValueError(f"actuator controls must be 4 finite values in [0, 1], got {c}")
    c.extend((0.0, 0.0, 0.0, 0.0))
    return mavlink2.MAVLink_set_actuator_control_target_message(int(time_usec), 0, target_system,
                                                                target_component, c)


RATE_TYPE_MASK = mavlink2.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
"""SET_ATTITUDE_TARGET's type_mask for body rates and thrust, the attitude ignored (128)."""


def rate_target(time_boot_ms: int, target_system: int, target_component: int, rates3, thrust: float) -> object:
    """SET_ATTITUDE_TARGET with body rates (rad/s, FRD) and a normalized thrust in [0, 1],
    the attitude ignored (``type_mask`` 128).

    Raises ValueError on a non-finite value or a thrust outside [0, 1]."""
    p, q, r = (float(v) for v in rates3)
    t = float(thrust)
    if not (0.0 <= t <= 1.0 and abs(p) < 1e3 and abs(q) < 1e3 and abs(r) < 1e3):   # NaN fails
        raise ValueError(f"rate target must be finite rates and a thrust in [0, 1], got {(p, q, r)}, {t}")
    return mavlink2.MAVLink_set_attitude_target_message(int(time_boot_ms), target_system, target_component,
                                                        RATE_TYPE_MASK, [1.0, 0.0, 0.0, 0.0], p, q, r, t)


def arm_disarm(target_system: int, target_component: int, arm: bool) -> object:
    """COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM."""
    return mavlink2.MAVLink_command_long_message(
        target_system, target_component, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0,
        1.0 if arm else 0.0, 0, 0, 0, 0, 0, 0)


def force_disarm(target_system: int, target_component: int) -> object:
    """COMMAND_LONG ARM_DISARM param1 = 0, param2 = 21196: stop the motors even in flight."""
    return mavlink2.MAVLink_command_long_message(
        target_system, target_component, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0,
        0.0, FORCE_DISARM_MAGIC, 0, 0, 0, 0, 0)


def statustext(severity: int, text: str, chunk_id: int) -> list:
    """STATUSTEXT message(s) of ``text`` (ASCII; at most 300 characters are sent).

    Up to 50 characters: one message with id 0. Longer: MAVLink 2 chunks, all with the
    non-zero ``chunk_id`` and ``chunk_seq`` 0, 1, ...; the last chunk is shorter than 50
    characters (an empty one follows a full last chunk), which ends the sequence.
    """
    data = text.encode("ascii", "replace")[:_TEXT_LEN * _MAX_CHUNKS - 1]
    if len(data) <= _TEXT_LEN:
        return [mavlink2.MAVLink_statustext_message(severity, data, 0, 0)]
    if not 0 < chunk_id < 65536:
        raise ValueError(f"chunk_id must be 1..65535, got {chunk_id}")
    chunks = [data[i:i + _TEXT_LEN] for i in range(0, len(data), _TEXT_LEN)]
    if len(chunks[-1]) == _TEXT_LEN:
        chunks.append(b"")
    return [mavlink2.MAVLink_statustext_message(severity, c, chunk_id, k) for k, c in enumerate(chunks)]


def set_offboard(target_system: int, target_component: int) -> object:
    """COMMAND_LONG MAV_CMD_DO_SET_MODE to PX4 OFFBOARD (param1 = 1, param2 = 6)."""
    return mavlink2.MAVLink_command_long_message(
        target_system, target_component, mavlink2.MAV_CMD_DO_SET_MODE, 0,
        float(mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(PX4_MAIN_OFFBOARD), 0, 0, 0, 0, 0)


def timesync_request(ts1_ns: int) -> object:
    """TIMESYNC request (tc1 = 0); the vehicle answers with its clock in tc1 and ts1 echoed."""
    return mavlink2.MAVLink_timesync_message(0, int(ts1_ns))


def daemon_heartbeat(healthy: bool) -> object:
    """The daemon's HEARTBEAT: onboard controller, no autopilot."""
    state = mavlink2.MAV_STATE_ACTIVE if healthy else mavlink2.MAV_STATE_CRITICAL
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_ONBOARD_CONTROLLER, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, state, 3)
