"""The plan's grid in arc length and the nominal on it.

The Riccati sweep steps through arc lengths evenly spaced in *nominal time*
(``riccati_step_s`` apart, :func:`time_grid`): the s-domain Riccati equation is as stiff as
the closed loop is fast divided by the speed, so steps in s proportional to the speed keep
RK4 equally accurate at 0.5 m/s and at 8 m/s. The plan's tables hold those nodes and the
midpoints in s between them (:func:`with_midpoints`), where RK4 evaluates A(s) and B(s)
anyway: the nominal (:func:`nominal_on_grid`, by differential flatness) is computed once,
on that grid, and refused where its attitude jumps between two samples.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import ManeuverError
from ..geometry.path import Path
from .flatness import FlatnessError, flat_nominal
from .profiles import Profile

__all__ = ["Nominal", "time_grid", "with_midpoints", "nominal_on_grid", "MAX_TURN_BETWEEN_SAMPLES_RAD"]

MAX_TURN_BETWEEN_SAMPLES_RAD = 0.2
"""A larger turn between two samples (and than 3 times the body rate allows) is a flip."""


def time_grid(path: Path, speed: Profile, step_s: float) -> np.ndarray:
    """Arc lengths evenly spaced in nominal time, step_s apart (last node at the end)."""
    s_fine = path.s_nodes
    v = speed.evaluate(s_fine)[0]
    if np.min(v) <= 0:
        raise ManeuverError(f"speed profile reaches {np.min(v):.3f} m/s: it must stay positive")
    t_fine = np.concatenate([[0.0], np.cumsum(np.diff(s_fine) * (1 / v[1:] + 1 / v[:-1]) / 2)])
    n = max(2, int(np.ceil(t_fine[-1] / step_s)) + 1)
    return np.interp(np.linspace(0.0, t_fine[-1], n), t_fine, s_fine)


def with_midpoints(nodes: np.ndarray) -> np.ndarray:
    """Nodes at the even indices, the midpoints in s between them at the odd ones."""
    s = np.empty(2 * len(nodes) - 1)
    s[0::2] = nodes
    s[1::2] = (nodes[:-1] + nodes[1:]) / 2
    return s


class Nominal(NamedTuple):
    """The nominal on a grid: path frames F, curvature k, state x, input u, dx = x'(s),
    speed v and attitude R."""

    F: np.ndarray
    k: np.ndarray
    x: np.ndarray
    u: np.ndarray
    dx: np.ndarray
    v: np.ndarray
    R: np.ndarray


def nominal_on_grid(model, path, speed, yaw, s, yaw_mode: str) -> Nominal:
    """The flat nominal of ``path`` flown at ``speed`` with ``yaw`` on the grid ``s``.

    Raises
    ------
    ManeuverError
        Where the flat map fails or the attitude flips between two samples (the message says
        where in s and what to change).
    """
    c, F, k, dk, ddk = path.evaluate(s)
    v4 = speed.evaluate(s)
    try:
        x, u, R = flat_nominal(model, F, k, dk, ddk, c, v4, yaw.evaluate(s), yaw_mode)
    except FlatnessError as exc:
        q = float(s[exc.index])
        raise ManeuverError(f"nominal: {exc.what} at s = {q:.2f} m in "
                            f"{path.segment_at(q).name!r} (yaw mode {yaw_mode}): {exc.remedy}") from None
    _check_attitude_continuity(s, R, x[:, 9:12], v4[0], path, yaw_mode)
    with np.errstate(all="ignore"):      # roll-pitch-yaw rates are singular at pitch +-90 deg
        dx = model.f(x.T, u.T).T / v4[0][:, None]
    dx[:, 3:6] = np.where(np.isfinite(dx[:, 3:6]), dx[:, 3:6], 0.0)
    return Nominal(F, k, x, u, dx, v4[0], R)


def _check_attitude_continuity(s, R, omega, v, path, yaw_mode: str) -> None:
    """Refuse a nominal whose attitude jumps between two samples.

    Where the nose reference crosses the thrust axis (fixed yaw in a loop flown in the
    reference's plane) or the path's heading reverses (tangent yaw through the vertical), the
    flat map's attitude flips by 180 deg about the thrust axis between two samples; the body
    rates at the samples do not show it, the turn between them does. A turn larger than
    :data:`MAX_TURN_BETWEEN_SAMPLES_RAD` and than 3 times the body rate over the sample
    interval is such a jump.
    """
    if len(s) < 2:
        return
    cos_turn = (np.einsum("nji,nji->n", R[:-1], R[1:]) - 1.0) / 2.0
    turn = np.arccos(np.clip(cos_turn, -1.0, 1.0))
    dt = np.diff(s) / ((v[:-1] + v[1:]) / 2)
    rate = np.maximum(np.linalg.norm(omega[:-1], axis=1), np.linalg.norm(omega[1:], axis=1))
    jump = (turn > MAX_TURN_BETWEEN_SAMPLES_RAD) & (turn > 3.0 * rate * dt)
    if np.any(jump):
        i = int(np.argmax(jump))
        q = float(s[i])
        raise ManeuverError(
            f"nominal: the attitude flips by {np.degrees(turn[i]):.0f} deg at s = {q:.2f} m in "
            f"{path.segment_at(q).name!r} (yaw mode {yaw_mode}): the nose reference crosses the "
            "thrust axis there (or the path's heading reverses); use yaw mode velocity for a "
            "loop flown nose-first, or another yaw")
