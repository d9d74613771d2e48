"""Ground contact at z = 0 (NED: z <= 0 is above ground), crash and safety limits."""
from __future__ import annotations

import math
from dataclasses import dataclass

from .status import ExitCode, SimStop

__all__ = ["Ground", "Limits", "check_limits"]


@dataclass(frozen=True)
class Limits:
    """Beyond these the simulation stops (exit code LIMIT)."""

    max_speed_m_s: float = 60.0
    max_body_rate_rad_s: float = 60.0


class Ground:
    """A flat rigid ground with friction that stops a landed vehicle.

    When the vehicle reaches z >= 0 it is put on the ground: z = 0, velocity and body
    rates zero, attitude levelled (heading kept), as a quadrotor settles on its legs.
    Touching down faster than ``crash_speed_m_s`` or tilted more than
    ``crash_tilt_rad`` raises :class:`SimStop` (CRASH). Upward net force lifts it off
    again through the normal dynamics.
    """

    def __init__(self, crash_speed_m_s: float, crash_tilt_rad: float = math.radians(60.0)):
        self.crash_speed_m_s = float(crash_speed_m_s)
        self.cos_crash_tilt = math.cos(crash_tilt_rad)
        self.on_ground = False
        self.survive_impact = False
        """The next touchdown, however hard, is recorded in :attr:`impacts`, not a crash (the
        fall of an injected in-air reboot, :mod:`firmware_sim.reboot`); cleared by any touchdown."""
        self.impacts: list = []
        """``{"t_s", "speed_m_s", "tilt_deg"}`` of the hard touchdowns survived."""

    def apply(self, s, t_s: float):
        """Return the state after ground contact (``s`` itself when airborne)."""
        if s[2] < 0.0:
            self.on_ground = False
            return s
        (px, py, _, qw, qx, qy, qz, vx, vy, vz, _, _, _) = s
        if not self.on_ground:
            speed = math.sqrt(vx * vx + vy * vy + vz * vz)
            up = 1.0 - 2.0 * (qx * qx + qy * qy)       # R22: cosine of the tilt
            tilt_deg = math.degrees(math.acos(max(-1.0, min(1.0, up))))
            survive, self.survive_impact = self.survive_impact, False
            if survive and (speed > self.crash_speed_m_s or up < self.cos_crash_tilt):
                self.impacts.append({"t_s": t_s, "speed_m_s": speed, "tilt_deg": tilt_deg})
            elif speed > self.crash_speed_m_s:
                raise SimStop(ExitCode.CRASH, f"crash at t={t_s:.3f} s: touched down at "
                              f"{speed:.2f} m/s (limit {self.crash_speed_m_s:g} m/s)")
            elif up < self.cos_crash_tilt:
                raise SimStop(ExitCode.CRASH, f"crash at t={t_s:.3f} s: touched down tilted {tilt_deg:.0f} deg")
        self.on_ground = True
        yaw = math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))
        return (px, py, 0.0, math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2),
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def check_limits(s, t_s: float, limits: Limits) -> None:
    """Raise :class:`SimStop` on a non-finite state or one beyond ``limits``."""
    if not math.isfinite(sum(s)):   # NaN and inf propagate through the sum
        raise SimStop(ExitCode.NON_FINITE, f"non-finite state at t={t_s:.3f} s")
    v2 = s[7] * s[7] + s[8] * s[8] + s[9] * s[9]
    if v2 > limits.max_speed_m_s ** 2:
        raise SimStop(ExitCode.LIMIT, f"speed {math.sqrt(v2):.1f} m/s beyond "
                      f"{limits.max_speed_m_s:g} m/s at t={t_s:.3f} s")
    w2 = s[10] * s[10] + s[11] * s[11] + s[12] * s[12]
    if w2 > limits.max_body_rate_rad_s ** 2:
        raise SimStop(ExitCode.LIMIT, f"body rate {math.sqrt(w2):.1f} rad/s beyond "
                      f"{limits.max_body_rate_rad_s:g} rad/s at t={t_s:.3f} s")
