"""Feasibility of a nominal maneuver: rotor limits, thrust and speed along arc length."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Feasibility", "check_feasibility"]


@dataclass(frozen=True)
class Feasibility:
    """What a nominal needs, and where (s) and by how much it exceeds the vehicle.

    ``violations`` holds one line per violated limit: the worst point and the s-range.
    """

    feasible: bool
    violations: tuple[str, ...]
    thrust_n: tuple[float, float]
    rotor_force_n: tuple[float, float]
    torque_max_abs_nm: tuple[float, float, float]
    speed_m_s: tuple[float, float]


def _ranges(s: np.ndarray, bad: np.ndarray) -> str:
    idx = np.flatnonzero(bad)
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    parts = [f"{s[a]:.2f}-{s[b]:.2f} m" for a, b in zip(starts[:3], ends[:3])]
    more = f" and {len(starts) - 3} more" if len(starts) > 3 else ""
    return ", ".join(parts) + more


def check_feasibility(s, u, rotor_forces_n, speed_m_s, max_rotor_thrust_n: float,
                      min_speed_m_s: float, segment_of, attitude=None,
                      max_tilt_rad: float = np.pi, body_rates_rad_s=None,
                      max_body_rate_rad_s=None) -> Feasibility:
    """Check a nominal sampled at arc lengths ``s``.

    Parameters
    ----------
    s : (N,) arc lengths; u : (N,4) nominal inputs; rotor_forces_n : (N,4) their rotor
    forces by the inverse of eq 34; speed_m_s : (N,); segment_of : callable s -> name;
    attitude : (N,3,3) nominal attitude, body to NED (None: the tilt is not checked);
    max_tilt_rad : the largest angle of the thrust axis from the vertical (the maneuver
    file's ``limits.max_tilt_deg``); body_rates_rad_s : (N,3) nominal body rates and
    max_body_rate_rad_s : (3,) the largest the autopilot is sent (``rate_interface``; None:
    not checked): a rate the output clips cannot be flown.
    """
    s = np.asarray(s)
    out: list[str] = []
    f = np.asarray(rotor_forces_n)
    hi = f.max(axis=1)
    lo = f.min(axis=1)
    if np.any(hi > max_rotor_thrust_n):
        i = int(np.argmax(hi))
        out.append(f"rotor {int(np.argmax(f[i])) + 1} needs {hi[i]:.2f} N > max_rotor_thrust_n "
                   f"{max_rotor_thrust_n:.2f} N (by {hi[i] - max_rotor_thrust_n:.2f} N) at "
                   f"s = {s[i]:.2f} m in {segment_of(s[i])!r}; over at "
                   f"{_ranges(s, hi > max_rotor_thrust_n)}")
    if np.any(lo < 0.0):
        i = int(np.argmin(lo))
        out.append(f"rotor {int(np.argmin(f[i])) + 1} needs {lo[i]:.2f} N < 0 (rotors only push) "
                   f"at s = {s[i]:.2f} m in {segment_of(s[i])!r}; negative at {_ranges(s, lo < 0)}")
    v = np.asarray(speed_m_s)
    if np.any(v < min_speed_m_s):
        i = int(np.argmin(v))
        out.append(f"speed {v[i]:.3f} m/s < min_speed_m_s {min_speed_m_s:.3f} at s = {s[i]:.2f} m "
                   f"in {segment_of(s[i])!r}: maneuver regulation needs ds/dt bounded away from 0")
    if attitude is not None and max_tilt_rad < np.pi:
        out += _tilt_violation(s, np.asarray(attitude), max_tilt_rad, segment_of)
    if body_rates_rad_s is not None and max_body_rate_rad_s is not None:
        out += _rate_violations(s, np.asarray(body_rates_rad_s), np.asarray(max_body_rate_rad_s), segment_of)
    torque = np.abs(u[:, 1:]).max(axis=0)
    return Feasibility(
        feasible=not out, violations=tuple(out),
        thrust_n=(float(u[:, 0].min()), float(u[:, 0].max())),
        rotor_force_n=(float(lo.min()), float(hi.max())),
        torque_max_abs_nm=tuple(float(t) for t in torque),
        speed_m_s=(float(v.min()), float(v.max())),
    )


def _tilt_violation(s, R, max_tilt_rad: float, segment_of) -> list[str]:
    """The tilt of the body z axis from the NED down axis, against ``max_tilt_rad``."""
    tilt = np.arccos(np.clip(R[:, 2, 2], -1.0, 1.0))
    over = tilt > max_tilt_rad
    if not np.any(over):
        return []
    i = int(np.argmax(tilt))
    return [f"tilt {np.degrees(tilt[i]):.1f} deg > limits.max_tilt_deg {np.degrees(max_tilt_rad):.1f} "
            f"at s = {s[i]:.2f} m in {segment_of(s[i])!r}; over at {_ranges(s, over)}"]


def _rate_violations(s, omega, max_rate, segment_of) -> list[str]:
    """Each body axis whose nominal rate exceeds ``max_rate`` (the rates output clips there)."""
    out = []
    for axis, name in enumerate(("roll", "pitch", "yaw")):
        over = np.abs(omega[:, axis]) > max_rate[axis]
        if np.any(over):
            i = int(np.argmax(np.abs(omega[:, axis])))
            out.append(f"{name} rate {abs(omega[i, axis]):.2f} rad/s > max_body_rate_rad_s {max_rate[axis]:.2f} "
                       f"at s = {s[i]:.2f} m in {segment_of(s[i])!r}; over at {_ranges(s, over)}")
    return out
