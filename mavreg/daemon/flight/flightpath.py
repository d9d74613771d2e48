"""Hover-LQR reference ramps around a maneuver: take-off, run-in, stop at the exit, landing.

Pure functions of numbers and a plan (no I/O). Every ramp is a degree-7 C^3 ramp of
:mod:`mavreg.control.controllers.hover` within the hover limits, except where a ramp must meet the
maneuver's own speed (run-in, stop at the exit): there the limits are raised just enough.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...control.controllers.hover import HoverParams, Ramp, hold_ramp, plan_ramp
from ...model.rotation import rpy_to_matrix

__all__ = ["Entry", "entry_of", "takeoff_ramps", "run_in_ramps", "stop_ramp", "land_ramp"]

_ZERO = np.zeros(3)


class Entry:
    """Where and how a plan is entered: hold point, yaw, entry velocity and acceleration (NED)."""

    def __init__(self, plan, hover: HoverParams, run_in_m: float, offset_m=(0.0, 0.0, 0.0)):
        x0 = np.asarray(plan.entry_state, dtype=float)
        self.position_m = x0[:3] + np.asarray(offset_m, dtype=float)   # off the path: experiments
        self.yaw_rad = float(x0[5])
        self.velocity_m_s = rpy_to_matrix(*x0[3:6]) @ x0[6:9]
        speed = float(np.linalg.norm(self.velocity_m_s))
        tangent = self.velocity_m_s / speed if speed > 1e-6 else np.array([1.0, 0.0, 0.0])
        ds = min(0.05, plan.length_m / 100.0)
        speed1 = float(np.linalg.norm(np.asarray(plan.nominal_state(ds), dtype=float)[6:9]))
        self.accel_m_s2 = tangent * speed * (speed1 - speed) / ds
        self.params = replace(hover, max_speed_m_s=max(hover.max_speed_m_s, speed),
                              max_accel_m_s2=max(hover.max_accel_m_s2,
                                                 1.5 * float(np.linalg.norm(self.accel_m_s2))))
        # a degree-7 ramp from rest to speed v needs about 1.2 v^2 / a of run
        run_in = max(run_in_m, 1.3 * speed * speed / self.params.max_accel_m_s2)
        self.hold_m = self.position_m - run_in * tangent


def entry_of(plan, hover: HoverParams, run_in_m: float, offset_m=(0.0, 0.0, 0.0)) -> Entry:
    """The entry of ``plan``; ``offset_m`` (NED) moves the run-in's end (and the hold point)
    off the nominal entry position, the velocity and acceleration stay the entry's."""
    return Entry(plan, hover, run_in_m, offset_m)


def takeoff_ramps(ground_m: np.ndarray, yaw0: float, entry: Entry, spool_s: float,
                  hover: HoverParams) -> list[Ramp]:
    """Sit still for the spool-up, climb vertically to the hold altitude, move to the hold point."""
    p = np.asarray(ground_m, dtype=float)
    sit = hold_ramp(p, yaw0)
    sit = Ramp(sit.coeffs, spool_s, sit.end_position_m, sit.end_velocity_m_s, yaw0)
    climb_to = np.array([p[0], p[1], entry.hold_m[2]])
    return [sit, plan_ramp(p, _ZERO, yaw0, climb_to, _ZERO, yaw0, hover),
            plan_ramp(climb_to, _ZERO, yaw0, entry.hold_m, _ZERO, entry.yaw_rad, hover)]


def run_in_ramps(hold_m: np.ndarray, hold_yaw: float, entry: Entry, hover: HoverParams) -> list[Ramp]:
    """Move to the entry's hold point if elsewhere, then accelerate onto the entry state."""
    ramps = []
    if np.linalg.norm(entry.hold_m - hold_m) > 0.02 or abs(entry.yaw_rad - hold_yaw) > 0.01:
        ramps.append(plan_ramp(hold_m, _ZERO, hold_yaw, entry.hold_m, _ZERO, entry.yaw_rad, hover))
    ramps.append(plan_ramp(entry.hold_m, _ZERO, entry.yaw_rad, entry.position_m, entry.velocity_m_s,
                           entry.yaw_rad, entry.params, a1=entry.accel_m_s2))
    return ramps


def stop_ramp(p_m: np.ndarray, v_m_s: np.ndarray, yaw: float, hover: HoverParams) -> Ramp:
    """From the maneuver's exit (position, velocity) to rest a little further on."""
    speed = float(np.linalg.norm(v_m_s))
    stop = p_m + v_m_s * (1.3 * speed / hover.max_accel_m_s2 + 0.05)
    params = replace(hover, max_speed_m_s=max(hover.max_speed_m_s, speed))
    return plan_ramp(p_m, v_m_s, yaw, stop, _ZERO, yaw, params, min_duration_s=0.2)


def land_ramp(hold_m: np.ndarray, yaw: float, ground_z_m: float, slow_altitude_m: float,
              land_speed_m_s: float, hover: HoverParams) -> Ramp:
    """Descend to ``slow_altitude_m`` above the ground, then keep sinking at ``land_speed_m_s``."""
    slow = np.array([hold_m[0], hold_m[1], ground_z_m - slow_altitude_m])
    return plan_ramp(hold_m, _ZERO, yaw, slow, np.array([0.0, 0.0, land_speed_m_s]), yaw, hover)
