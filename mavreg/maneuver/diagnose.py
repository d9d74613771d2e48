"""Why a plan failed, in the user's terms: what, where (segment and s), and what to change.

The gain schedule fails for a few reasons a user can act on, and the numbers that fail
(a Riccati solution that blows up at node 8024) name none of them. These functions look at
the nominal where it failed and say which it is:

- the roll-pitch-yaw singularity: the paper's attitude coordinates, and so its transverse
  linearization, are singular at pitch +-90 deg (their kinematics divide by cos(pitch)); a
  loop flown nose-first passes it;
- a speed too low for the s-domain design (its dynamics divide by the speed);
- rotors near their limits (no authority left to regulate);
- a curvature too high for the speed.

Pure: numbers in, a sentence out.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..config.vehicle import G

__all__ = ["EULER_LIMIT_DEG", "euler_singularity", "explain_divergence"]

EULER_LIMIT_DEG = 89.0
"""A nominal whose pitch comes closer than 1 deg to +-90 deg is refused before the sweep."""

_NEAR_EULER_DEG = 80.0
_LOW_SPEED_M_S = 0.3
_ROTOR_MARGIN = 0.05


def euler_singularity(s, pitch_rad, segment_of: Callable[[float], str],
                      limit_deg: float = EULER_LIMIT_DEG) -> str | None:
    """The sentence for a nominal pitch beyond ``limit_deg`` (None if it stays within)."""
    pitch = np.degrees(np.abs(np.asarray(pitch_rad)))
    if pitch.max() < limit_deg:
        return None
    i = int(np.argmax(pitch))
    return (f"the nominal attitude reaches pitch {np.degrees(pitch_rad[i]):+.1f} deg at "
            f"s = {s[i]:.2f} m in {segment_of(s[i])!r}: the paper's roll-pitch-yaw attitude is "
            "singular at +-90 deg (a loop flown nose-first passes it). Plan it with a controller "
            "in the SO(3) form (attitude_error: so3, as params/controller/design.yaml and "
            f"realistic.yaml), or keep the pitch within +-{limit_deg:.0f} deg (fly the loop as a "
            "barrel roll, heading across the loop's plane)")


def explain_divergence(s_fail: float, s, pitch_rad, speed_m_s, rotor_forces_n,
                       max_rotor_thrust_n: float, curvature_1_m, segment_of) -> str:
    """The likely causes of a gain schedule that diverged at ``s_fail``, most likely first,
    with what to change; the nominal is sampled at ``s``."""
    s = np.asarray(s)
    near = np.abs(s - s_fail) <= max(1.0, 0.05 * (s[-1] - s[0]))
    where = f"at s = {s_fail:.2f} m in {segment_of(s_fail)!r}"
    causes = []
    pitch = np.degrees(np.abs(np.asarray(pitch_rad)[near]))
    if pitch.max() >= _NEAR_EULER_DEG:
        causes.append(f"the nominal pitch reaches {pitch.max():.1f} deg there, near the "
                      "roll-pitch-yaw singularity at 90 deg: keep the pitch below "
                      f"{_NEAR_EULER_DEG:.0f} deg (fly a barrel roll rather than a loop "
                      "nose-first, or yaw the nose out of the loop's plane)")
    v = np.asarray(speed_m_s)[near]
    if v.min() < _LOW_SPEED_M_S:
        causes.append(f"the speed falls to {v.min():.2f} m/s there and the design is "
                      f"scheduled by arc length, whose dynamics divide by the speed: keep it "
                      f"above {_LOW_SPEED_M_S} m/s")
    f = np.asarray(rotor_forces_n)[near]
    top, bottom = f.max(), f.min()
    if top > (1 - _ROTOR_MARGIN) * max_rotor_thrust_n or bottom < _ROTOR_MARGIN * max_rotor_thrust_n:
        causes.append(f"the rotors need {bottom:.2f} to {top:.2f} N there (limit "
                      f"{max_rotor_thrust_n:.2f} N), leaving no authority to regulate: lower the "
                      "speed or widen the curve")
    kappa = np.asarray(curvature_1_m)[near]
    vv = np.asarray(speed_m_s)[near]
    if np.max(kappa * vv ** 2) > 4 * G:
        i = int(np.argmax(kappa * vv ** 2))
        causes.append(f"the curve asks {kappa[i] * vv[i] ** 2 / G:.1f} g of centripetal "
                      f"acceleration (radius {1 / max(kappa[i], 1e-9):.2f} m at {vv[i]:.1f} m/s): "
                      "widen the curve or slow down")
    if not causes:
        causes.append("no limit of the nominal is near there: try a smaller riccati_step_s in "
                      "the controller file, or lighter weights (q_*) on the fastest states")
    return f"the gain schedule diverged {where}; " + "; ".join(causes)
