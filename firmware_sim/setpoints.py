"""Offboard position and velocity set-points (SET_POSITION_TARGET_LOCAL_NED), as MAVSDK's
Offboard plugin sends them (``set_position_ned``, ``set_velocity_ned``,
``set_position_velocity_ned``).

Taken from our own system or a configured peer, addressed to us (``target_system`` ours,
``target_component`` ours or 0), in ``MAV_FRAME_LOCAL_NED``, with the accelerations masked
(the emulator has no acceleration set-points: ``unsupported``; the yaw rate is not used), at least a
position or a velocity given, every used field finite (else ``non_finite``). A valid one keeps
the offboard stream alive as an actuator target does, and OFFBOARD then flies it with the
autopilot's own cascade (:meth:`firmware_sim.stabilizer.Stabilizer.track`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Setpoint", "parse_position_target", "take_setpoint", "IGNORE_POSITION", "IGNORE_VELOCITY",
           "IGNORE_ACCEL", "IGNORE_YAW"]

IGNORE_POSITION = 0b111
IGNORE_VELOCITY = 0b111 << 3
IGNORE_ACCEL = 0b111 << 6
IGNORE_YAW = 1 << 10
MAV_FRAME_LOCAL_NED = 1


@dataclass(frozen=True)
class Setpoint:
    """A position and/or velocity set-point (NED, m and m/s; ``None``: not given)."""

    position_ned: tuple | None
    velocity_ned: tuple
    yaw_rad: float | None


def parse_position_target(msg, system_id: int, component_id: int, peers) -> tuple:
    """``(drop reason or None, Setpoint or None)`` of a SET_POSITION_TARGET_LOCAL_NED."""
    if msg.get_srcSystem() != system_id and msg.get_srcSystem() not in peers:
        return "foreign_system", None
    if msg.target_system != system_id or msg.target_component not in (0, component_id):
        return "wrong_target", None
    mask = msg.type_mask
    if msg.coordinate_frame != MAV_FRAME_LOCAL_NED or mask & IGNORE_ACCEL != IGNORE_ACCEL:
        return "unsupported", None
    has_pos, has_vel = not mask & IGNORE_POSITION, not mask & IGNORE_VELOCITY
    if not (has_pos or has_vel):
        return "unsupported", None
    pos = (msg.x, msg.y, msg.z) if has_pos else None
    vel = (msg.vx, msg.vy, msg.vz) if has_vel else (0.0, 0.0, 0.0)
    yaw = None if mask & IGNORE_YAW else msg.yaw
    used = (pos or ()) + vel + ((yaw,) if yaw is not None else ())
    if not all(math.isfinite(v) for v in used):
        return "non_finite", None
    return None, Setpoint(pos, vel, yaw)


def take_setpoint(ap, msg, t_s: float) -> None:
    """The autopilot ``ap`` takes a SET_POSITION_TARGET_LOCAL_NED at ``t_s`` (drops counted):
    flown in OFFBOARD until the next actuator target; it keeps the offboard stream alive."""
    cfg = ap.cfg
    reason, sp = parse_position_target(msg, cfg.system_id, cfg.component_id, cfg.peer_system_ids)
    if reason is not None:
        ap.drops[reason] += 1
        return
    ap.setpoint = sp
    if t_s - ap.last_target_t > 1.0 / cfg.stream_min_hz:
        ap.stream_start_t = t_s
    ap.last_target_t = t_s
