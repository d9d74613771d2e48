"""Offboard set-points: position and velocity (SET_POSITION_TARGET_LOCAL_NED), as MAVSDK's
Offboard plugin sends them (``set_position_ned``, ``set_velocity_ned``,
``set_position_velocity_ned``), and body rates with a collective thrust (SET_ATTITUDE_TARGET).

Taken from our own system or a configured peer, addressed to us (``target_system`` ours,
``target_component`` ours or 0), in ``MAV_FRAME_LOCAL_NED``, with the accelerations masked
(the emulator has no acceleration set-points: ``unsupported``; the yaw rate is not used), at least a
position or a velocity given, every used field finite (else ``non_finite``). A valid one keeps
the offboard stream alive as an actuator target does, and OFFBOARD then flies it with the
autopilot's own cascade (:meth:`firmware_sim.stabilizer.Stabilizer.track`).

SET_ATTITUDE_TARGET (#82) is taken as PX4 OFFBOARD takes a rate set-point: ``type_mask`` exactly
:data:`RATES_MASK` (128, ATTITUDE_IGNORE: the quaternion is not read; ``body_roll_rate``,
``body_pitch_rate``, ``body_yaw_rate`` in rad/s, body FRD; ``thrust`` the normalized collective,
0..1; ``thrust_body`` not read). Its source and target rules are the actuator target's
(:meth:`firmware_sim.autopilot.Autopilot.target_drop_reason`: our own system, the offboard
peer's component). Then, in order: another mask ``unsupported`` (with one STATUSTEXT a second
at most), a non-finite used field ``non_finite``, a rate beyond :data:`MAX_BODY_RATE_RAD_S` or a
thrust outside [0, 1] (+- 1e-6) ``out_of_range``. A valid one keeps the offboard stream alive
and OFFBOARD flies it with :class:`firmware_sim.rate_loop.RateLoop`, until a set-point of
another kind arrives (the last kind received wins, as on PX4).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from . import modes

__all__ = ["Setpoint", "parse_position_target", "take_setpoint", "IGNORE_POSITION", "IGNORE_VELOCITY",
           "IGNORE_ACCEL", "IGNORE_YAW", "RATES_MASK", "MAX_BODY_RATE_RAD_S", "rate_target_reason",
           "target_content_reason", "take_target"]

IGNORE_POSITION = 0b111
IGNORE_VELOCITY = 0b111 << 3
IGNORE_ACCEL = 0b111 << 6
IGNORE_YAW = 1 << 10
MAV_FRAME_LOCAL_NED = 1
RATES_MASK = 128
"""ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE alone: body rates and thrust given."""
MAX_BODY_RATE_RAD_S = 20.0
"""A larger rate set-point is ``out_of_range`` (the simulation stops at 60 rad/s)."""
MASK_WARNING_PERIOD_S = 1.0


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
    flown in OFFBOARD until a target of another kind; it keeps the offboard stream alive."""
    cfg = ap.cfg
    reason, sp = parse_position_target(msg, cfg.system_id, cfg.component_id, cfg.peer_system_ids)
    if reason is not None:
        ap.drops[reason] += 1
        return
    ap.setpoint = sp
    ap.rate_mode = False
    ap.rates.clear()
    if t_s - ap.last_target_t > 1.0 / cfg.stream_min_hz:
        ap.stream_start_t = t_s
    ap.last_target_t = t_s


def rate_target_reason(msg, tolerance: float) -> str | None:
    """Why a SET_ATTITUDE_TARGET's content is refused (``None``: valid); the source and target
    checks are the caller's."""
    if msg.type_mask != RATES_MASK:
        return "unsupported"
    rates = (msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate)
    if not all(math.isfinite(v) for v in (*rates, msg.thrust)):
        return "non_finite"
    if max(abs(v) for v in rates) > MAX_BODY_RATE_RAD_S or not -tolerance <= msg.thrust <= 1.0 + tolerance:
        return "out_of_range"
    return None


def target_content_reason(msg, tolerance: float) -> str | None:
    """Why the content of an offboard target (SET_ACTUATOR_CONTROL_TARGET or SET_ATTITUDE_TARGET)
    is refused (``None``: valid); the source and target checks are the autopilot's."""
    if msg.get_type() == "SET_ATTITUDE_TARGET":
        return rate_target_reason(msg, tolerance)
    if msg.group_mlx != 0:
        return "unsupported"
    c = msg.controls
    if not math.isfinite(sum(c)):
        return "non_finite"
    if min(c[0], c[1], c[2], c[3]) < -tolerance or max(c[0], c[1], c[2], c[3]) > 1.0 + tolerance:
        return "out_of_range"
    return None


def take_target(ap, msg, t_s: float) -> None:
    """The autopilot ``ap`` takes an offboard target received at ``t_s`` (drops counted): rotor
    forces, or body rates and thrust; the first valid one names the offboard peer's component."""
    reason = ap.target_drop_reason(msg)
    if ap.offboard_component is None and reason is None:
        ap.offboard_component = msg.get_srcComponent()
    rates = msg.get_type() == "SET_ATTITUDE_TARGET"
    if reason is not None:
        ap.drops[reason] += 1
        if rates and reason == "unsupported" and t_s - ap.mask_warning_t >= MASK_WARNING_PERIOD_S:
            ap.mask_warning_t = t_s
            ap._out.append(ap._statustext(4, f"attitude target: type_mask {msg.type_mask} refused (only 128)"))
        return
    cfg = ap.cfg
    if rates:
        thrust = max(0.0, min(1.0, msg.thrust))
        ap.rates.push(t_s, (msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate, thrust))
    else:
        fmax = cfg.max_rotor_thrust_n
        ap.target_n = tuple(fmax * (0.0 if x < 0.0 else (1.0 if x > 1.0 else x)) for x in msg.controls[:4])
        ap.rates.clear()
        ap.setpoint = None
    ap.rate_mode = rates             # a position set-point stays, flown until the rates reach the loop
    if t_s - ap.last_target_t > 1.0 / cfg.stream_min_hz:
        ap.stream_start_t = t_s
    ap.last_target_t = t_s
    ap.target_count += 1
    if ap.armed and ap.mode == modes.OFFBOARD:
        ap.applied_count += 1
    else:
        ap.drops["not_armed_or_not_offboard"] += 1
