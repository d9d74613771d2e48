"""The autopilot's own fallback controller: level, kill velocity, hold altitude, land.

A plain cascade, written for the emulator alone (nothing shared with mavreg):

1. velocity loop (NED): horizontal velocity to zero, then, once braked, from a position P
   loop (PX4's hold and land keep their position, so a steady wind leaves an offset, not a
   drift); vertical velocity from an
   altitude P loop (HOLD) or a fixed descent rate (LAND); gives a desired
   acceleration, saturated, hence a desired force ``F = m (a - g e3)``;
2. desired attitude: body -z along ``F``, heading held;
3. attitude loop on the **quaternion** error (no Euler singularity, shortest way
   round, works from inverted), rate command saturated;
4. rate loop with gyroscopic compensation gives body torques;
5. thrust = projection of ``F`` on the current thrust axis (with a floor, so there is
   torque authority even upside down), mixed into rotor forces with roll/pitch first.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .physics import G, quat_mul, yaw_of

__all__ = ["StabilizerGains", "Stabilizer"]


@dataclass(frozen=True)
class StabilizerGains:
    """Gains and limits of the fallback controller (SI)."""

    kv_xy_per_s: float = 1.5
    kp_z_per_s: float = 1.5
    kv_z_per_s: float = 3.0
    max_climb_m_s: float = 2.0
    max_accel_xy_m_s2: float = 7.0
    max_accel_up_m_s2: float = 15.0
    max_accel_down_m_s2: float = 5.0
    kp_att_per_s: float = 8.0
    kw_per_s: float = 20.0
    max_rate_rad_s: float = 12.0
    max_yaw_rate_rad_s: float = 2.0
    min_thrust_fraction_of_weight: float = 0.2
    min_hold_height_m: float = 0.5
    """HOLD never targets an altitude lower than this above ground."""
    kp_xy_per_s: float = 1.0
    """Horizontal position gain (velocity per metre) of offboard position set-points and of
    the position HOLD and LAND keep."""
    max_speed_xy_m_s: float = 5.0
    brake_done_m_s: float = 1.0
    """HOLD and LAND brake to this horizontal speed before they keep a position."""


def _quat_from_matrix(c0, c1, c2):
    """Quaternion of the rotation matrix with columns ``c0, c1, c2``."""
    r00, r10, r20 = c0
    r01, r11, r21 = c1
    r02, r12, r22 = c2
    tr = r00 + r11 + r22
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        return (0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s)
    if r00 > r11 and r00 > r22:
        s = 2.0 * math.sqrt(1.0 + r00 - r11 - r22)
        return ((r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s)
    if r11 > r22:
        s = 2.0 * math.sqrt(1.0 + r11 - r00 - r22)
        return ((r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s)
    s = 2.0 * math.sqrt(1.0 + r22 - r00 - r11)
    return ((r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s)


class Stabilizer:
    """Fallback controller of HOLD and LAND; see the module docstring.

    Parameters
    ----------
    mass_kg, inertia_kg_m2, arm_length_m, drag_torque_ratio_m, max_rotor_thrust_n
        The vehicle as the autopilot knows it (nominal parameters).
    gains : StabilizerGains, optional
    """

    def __init__(self, mass_kg: float, inertia_kg_m2, arm_length_m: float,
                 drag_torque_ratio_m: float, max_rotor_thrust_n: float,
                 gains: StabilizerGains | None = None):
        self.m = float(mass_kg)
        self.J = inertia_kg_m2
        self.l = float(arm_length_m)
        self.k = float(drag_torque_ratio_m)
        self.fmax = float(max_rotor_thrust_n)
        self.g = gains if gains is not None else StabilizerGains()
        self.z_ref_m = -self.g.min_hold_height_m
        self.yaw_ref_rad = 0.0
        self.xy_ref_m: tuple[float, float] | None = None
        """Horizontal position HOLD and LAND keep; ``None``: velocity to zero only."""
        self._keep_pending = False

    def reset(self, s) -> None:
        """Capture the altitude to hold and the heading to keep from state ``s``; the
        horizontal position to keep is taken once the vehicle has braked (see :meth:`_keep_xy`)."""
        self.z_ref_m = min(s[2], -self.g.min_hold_height_m)
        self.yaw_ref_rad = yaw_of(s[3:7], self.yaw_ref_rad)
        self.xy_ref_m = None
        self._keep_pending = True

    def _keep_xy(self, s) -> tuple[float, float]:
        """Horizontal velocity set-point of HOLD and LAND. As PX4 does, brake first (velocity
        to zero); below :attr:`StabilizerGains.brake_done_m_s` keep a position: where the
        position loop brings the vehicle to rest, ``x + v / k_p``, so the set-point is
        continuous. Before any :meth:`reset` (HOLD on the ground) velocity to zero only."""
        g = self.g
        if self.xy_ref_m is None:
            if not self._keep_pending or math.hypot(s[7], s[8]) >= g.brake_done_m_s:
                return 0.0, 0.0
            self.xy_ref_m = (s[0] + s[7] / g.kp_xy_per_s, s[1] + s[8] / g.kp_xy_per_s)
        return self._speed_limited(g.kp_xy_per_s * (self.xy_ref_m[0] - s[0]),
                                   g.kp_xy_per_s * (self.xy_ref_m[1] - s[1]))

    def _speed_limited(self, vx: float, vy: float) -> tuple[float, float]:
        """A horizontal velocity set-point scaled down to ``max_speed_xy_m_s``."""
        h, top = math.hypot(vx, vy), self.g.max_speed_xy_m_s
        return (vx * top / h, vy * top / h) if h > top else (vx, vy)

    def hold(self, s):
        """Rotor forces (N) to level, keep ``xy_ref_m`` and hold ``z_ref_m``."""
        g = self.g
        vz_ref = max(-g.max_climb_m_s, min(g.max_climb_m_s, g.kp_z_per_s * (self.z_ref_m - s[2])))
        return self._control(s, vz_ref, *self._keep_xy(s))

    def land(self, s, descent_m_s: float):
        """Rotor forces (N) to level, keep ``xy_ref_m`` and descend at ``descent_m_s``."""
        return self._control(s, descent_m_s, *self._keep_xy(s))

    def track(self, s, position_ned, velocity_ned, yaw_rad):
        """Rotor forces (N) to a position and/or velocity set-point (offboard, PX4's
        SET_POSITION_TARGET_LOCAL_NED): a P position loop (speed limited) plus the velocity
        feed-forward; a ``None`` position axis is not held; ``yaw_rad`` ``None`` keeps the heading."""
        g = self.g
        v_ref = [0.0 if v is None else v for v in velocity_ned]
        if position_ned is not None:
            for i, gain in ((0, g.kp_xy_per_s), (1, g.kp_xy_per_s), (2, g.kp_z_per_s)):
                v_ref[i] += gain * (position_ned[i] - s[i])
        v_ref[0], v_ref[1] = self._speed_limited(v_ref[0], v_ref[1])
        vz_ref = max(-g.max_climb_m_s, min(g.max_climb_m_s, v_ref[2]))
        if yaw_rad is not None:
            self.yaw_ref_rad = yaw_rad
        return self._control(s, vz_ref, v_ref[0], v_ref[1])

    def _control(self, s, vz_ref: float, vx_ref: float = 0.0, vy_ref: float = 0.0):
        g = self.g
        (_, _, _, qw, qx, qy, qz, vx, vy, vz, p, q, r) = s
        # 1. velocity loop -> desired acceleration (NED)
        ax = g.kv_xy_per_s * (vx_ref - vx)
        ay = g.kv_xy_per_s * (vy_ref - vy)
        az = g.kv_z_per_s * (vz_ref - vz)
        az = max(-g.max_accel_up_m_s2, min(g.max_accel_down_m_s2, az))
        axy_max = min(g.max_accel_xy_m_s2, math.tan(math.radians(40.0)) * (G - az))
        axy = math.hypot(ax, ay)
        if axy > axy_max:
            ax *= axy_max / axy
            ay *= axy_max / axy
        fx, fy, fz = self.m * ax, self.m * ay, self.m * (az - G)    # fz < 0: upward
        fn = math.sqrt(fx * fx + fy * fy + fz * fz)
        # 2. desired attitude: body z (down) = -F/|F|, heading yaw_ref
        zb = (-fx / fn, -fy / fn, -fz / fn)
        xc = (math.cos(self.yaw_ref_rad), math.sin(self.yaw_ref_rad), 0.0)
        yb = (zb[1] * xc[2] - zb[2] * xc[1], zb[2] * xc[0] - zb[0] * xc[2], zb[0] * xc[1] - zb[1] * xc[0])
        yn = math.sqrt(yb[0] ** 2 + yb[1] ** 2 + yb[2] ** 2)
        yb = (yb[0] / yn, yb[1] / yn, yb[2] / yn)
        xb = (yb[1] * zb[2] - yb[2] * zb[1], yb[2] * zb[0] - yb[0] * zb[2], yb[0] * zb[1] - yb[1] * zb[0])
        qd = _quat_from_matrix(xb, yb, zb)
        # 3. attitude error q_e = qd^-1 q (body frame), shortest way round
        ew, ex, ey, ez = quat_mul((qd[0], -qd[1], -qd[2], -qd[3]), (qw, qx, qy, qz))
        if ew < 0:
            ew, ex, ey, ez = -ew, -ex, -ey, -ez
        vn = math.sqrt(ex * ex + ey * ey + ez * ez)
        if vn > 1e-12:
            angle = 2.0 * math.atan2(vn, ew)
            k = -g.kp_att_per_s * angle / vn
            wx, wy, wz = k * ex, k * ey, k * ez
        else:
            wx = wy = wz = 0.0
        wz = max(-g.max_yaw_rate_rad_s, min(g.max_yaw_rate_rad_s, 0.5 * wz))
        wn = math.sqrt(wx * wx + wy * wy + wz * wz)
        if wn > g.max_rate_rad_s:
            wx, wy, wz = (c * g.max_rate_rad_s / wn for c in (wx, wy, wz))
        # 4. rate loop: tau = J kw (w_des - w) + w x J w
        J = self.J
        ux, uy, uz = g.kw_per_s * (wx - p), g.kw_per_s * (wy - q), g.kw_per_s * (wz - r)
        hx = J[0][0] * p + J[0][1] * q + J[0][2] * r
        hy = J[1][0] * p + J[1][1] * q + J[1][2] * r
        hz = J[2][0] * p + J[2][1] * q + J[2][2] * r
        tx = J[0][0] * ux + J[0][1] * uy + J[0][2] * uz + (q * hz - r * hy)
        ty = J[1][0] * ux + J[1][1] * uy + J[1][2] * uz + (r * hx - p * hz)
        tz = J[2][0] * ux + J[2][1] * uy + J[2][2] * uz + (p * hy - q * hx)
        # 5. thrust along the current body -z axis, with a floor
        bz = (2.0 * (qx * qz + qw * qy), 2.0 * (qy * qz - qw * qx), 1.0 - 2.0 * (qx * qx + qy * qy))
        thrust = -(fx * bz[0] + fy * bz[1] + fz * bz[2])
        thrust = max(thrust, g.min_thrust_fraction_of_weight * self.m * G)
        return self.mix(thrust, tx, ty, tz)

    def mix(self, thrust_n: float, tx: float, ty: float, tz: float):
        """Rotor forces for thrust and torques; roll/pitch before thrust before yaw."""
        fmax = self.fmax
        d_roll = max(-fmax / 2, min(fmax / 2, tx / (2.0 * self.l)))
        d_pitch = max(-fmax / 2, min(fmax / 2, ty / (2.0 * self.l)))
        rp = max(abs(d_roll), abs(d_pitch))
        d_yaw = max(-0.15 * fmax, min(0.15 * fmax, tz / (4.0 * self.k)))
        lo = rp + abs(d_yaw)
        hi = fmax - lo
        base = thrust_n / 4.0
        if lo <= hi:
            base = max(lo, min(hi, base))
        else:
            base = fmax / 2
        f = (base + d_pitch - d_yaw, base - d_roll + d_yaw, base - d_pitch - d_yaw, base + d_roll + d_yaw)
        return tuple(0.0 if x < 0.0 else (fmax if x > fmax else x) for x in f)
