"""The state messages of one time: what the autopilot publishes each control period."""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from .physics import euler_from_quat

__all__ = ["state_messages"]


def state_messages(t_s: float, position, velocity, quat, rates) -> tuple:
    """``(ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED)`` with one ``time_boot_ms``.

    The Euler angles of ATTITUDE are those of ``quat`` (ZYX); both attitude messages
    carry ``rates`` (body p, q, r).
    """
    ms = int(round(t_s * 1000.0))
    x, y, z = position
    vx, vy, vz = velocity
    qw, qx, qy, qz = quat
    p, q, r = rates
    roll, pitch, yaw = euler_from_quat((qw, qx, qy, qz))
    return (
        mavlink2.MAVLink_attitude_message(ms, roll, pitch, yaw, p, q, r),
        mavlink2.MAVLink_attitude_quaternion_message(ms, qw, qx, qy, qz, p, q, r, (0.0, 0.0, 0.0, 0.0)),
        mavlink2.MAVLink_local_position_ned_message(ms, x, y, z, vx, vy, vz),
    )
