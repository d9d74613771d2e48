r"""The plan's nominal as a trajectory: timed by its speed profile.

A :class:`~mavreg.maneuver.plan.Plan` gives the nominal state and input as functions of the
arc length, :math:`\bar x(s)`, :math:`\bar u(s)`, and the speed :math:`v(s)` along the
path. A time-indexed tracker needs them as functions of time; the clock is

.. math:: \dot s = v(s), \qquad s(0) = 0,

integrated by classical RK4 on a uniform time grid (``step_s``, 1 ms by default, the
regulator's Riccati step) with :math:`v(s)` a cubic spline through the plan's nodes; between
grid nodes :math:`s(t)` is the cubic Hermite interpolant with :math:`\dot s = v(s)` at both
ends. Then :math:`\bar x(t) = \bar x(s(t))` (the plan's own Hermite interpolation in s, whose
slope is :math:`f(\bar x, \bar u)/v`, so :math:`\dot{\bar x} = f(\bar x, \bar u)` along the
clock) and :math:`\bar u(t)` is :math:`\bar u(s)` interpolated linearly in s, as the regulator
does.

After the path's end (:math:`t > T`) the reference flies on along the last nominal state's
velocity with its attitude and input: exact when the maneuver ends on a straight line at
constant speed, as the barrel roll's run-out does (0.5 m/s for its last 5 m). The speed
beyond either end is the end's.
"""
from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

from ..maneuver.plan import Plan
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import rpy_to_matrix
from .common import cross3

__all__ = ["Reference", "TimedNominal"]


@dataclass(frozen=True)
class Reference:
    """The timed nominal at one instant (SI, NED, body FRD)."""

    t: float
    s: float
    """Arc length of the reference (beyond the path's length after its end)."""
    x: np.ndarray
    """(12,) nominal state (p, roll pitch yaw, body velocity, body rates)."""
    u: np.ndarray
    """(4,) nominal input (f, g1, g2, g3)."""
    acceleration_ned_m_s2: np.ndarray
    """(3,) second time derivative of the nominal position."""
    angular_acceleration_rad_s2: np.ndarray
    """(3,) time derivative of the nominal body rates."""


class TimedNominal:
    """The nominal of ``plan`` as a function of time (see the module docstring).

    Parameters
    ----------
    plan : Plan
    step_s : float
        Time step of the clock's RK4 integration and of its grid.
    """

    def __init__(self, plan: Plan, step_s: float = 0.001):
        if not step_s > 0.0:
            raise ValueError(f"step_s must be positive, got {step_s}")
        self.plan = plan
        self.model = QuadrotorModel.from_vehicle(plan.vehicle)
        self.length_m = float(plan.length_m)
        self._speed = CubicSpline(plan.s, plan.speed_m_s)
        self._s0, self._s1 = float(plan.s[0]), float(plan.s[-1])
        self._knots = self._speed.x.tolist()
        self._pieces = self._speed.c.T.tolist()
        h = float(step_s)
        v = self._speed_scalar
        s = [0.0]
        while s[-1] < self.length_m:
            si = s[-1]
            k1 = v(si)
            k2 = v(si + 0.5 * h * k1)
            k3 = v(si + 0.5 * h * k2)
            k4 = v(si + h * k3)
            s.append(si + h / 6.0 * (k1 + 2.0 * (k2 + k3) + k4))
        self.step_s = h
        self.s_grid = np.array(s)
        self.t_grid = h * np.arange(len(s))
        self._v_grid = self.speed_at(self.s_grid)
        # the last grid interval straddles the end: the time the clock reaches it
        a, b = self.s_grid[-2], self.s_grid[-1]
        self.duration_s = float(self.t_grid[-2] + h * (self.length_m - a) / (b - a))
        self._x_end = plan.nominal_state(self.length_m)
        R_end = rpy_to_matrix(*self._x_end[3:6])
        v_end = R_end @ self._x_end[6:9]
        self._dir_end = v_end / np.linalg.norm(v_end)
        self._u_end = plan.u[-1].copy()

    def speed_at(self, s):
        """v(s) of the plan's speed profile (the end's value beyond either end)."""
        return self._speed(np.clip(s, self._s0, self._s1))

    def _speed_scalar(self, s: float) -> float:
        """:meth:`speed_at` of one arc length in plain floats, the same number: scipy's
        piecewise-polynomial sum (``c3 + c2 d + c1 d^2 + c0 d^3``, d from the piece's knot,
        in that order), the piece found by bisection (the clock's integration calls it
        about 90 000 times on the barrel roll)."""
        s = min(max(s, self._s0), self._s1)
        i = min(max(bisect_right(self._knots, s) - 1, 0), len(self._pieces) - 1)
        c0, c1, c2, c3 = self._pieces[i]
        d = s - self._knots[i]
        return ((c3 + c2 * d) + c1 * (d * d)) + c0 * (d * d * d)

    def s_at(self, t):
        """Arc length of the reference at time(s) ``t`` (s(0) = 0; clamped at t = 0)."""
        if isinstance(t, float):
            return self._s_at_scalar(t)
        t = np.asarray(t, dtype=float)
        h = self.step_s
        n = len(self.t_grid)
        past = t > self.t_grid[-1]
        tc = np.clip(t, 0.0, self.t_grid[-1])
        i = np.clip((tc / h).astype(int), 0, n - 2)
        u = (tc - self.t_grid[i]) / h
        s0, s1 = self.s_grid[i], self.s_grid[i + 1]
        v0, v1 = self._v_grid[i], self._v_grid[i + 1]
        h00, h10 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u
        h01, h11 = -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2
        s = h00 * s0 + h10 * h * v0 + h01 * s1 + h11 * h * v1
        s = np.where(past, self.s_grid[-1] + self._v_grid[-1] * (t - self.t_grid[-1]), s)
        return float(s) if s.ndim == 0 else s

    def _s_at_scalar(self, t: float) -> float:
        """:meth:`s_at` for one time, in plain floats (the trackers call it every step)."""
        h = self.step_s
        n = len(self.t_grid)
        if t > self.t_grid[-1]:
            return float(self.s_grid[-1] + self._v_grid[-1] * (t - self.t_grid[-1]))
        tc = max(t, 0.0)
        i = min(int(tc / h), n - 2)
        u = (tc - self.t_grid[i]) / h
        u2, u3 = u * u, u * u * u
        return float((2 * u3 - 3 * u2 + 1) * self.s_grid[i] + (u3 - 2 * u2 + u) * h * self._v_grid[i]
                     + (-2 * u3 + 3 * u2) * self.s_grid[i + 1] + (u3 - u2) * h * self._v_grid[i + 1])

    def t_of_s(self, s: float) -> float:
        """The time the reference reaches arc length ``s`` (0 <= s; linear between grid nodes)."""
        if s > self.s_grid[-1]:
            return float(self.t_grid[-1] + (s - self.s_grid[-1]) / self._v_grid[-1])
        return float(np.interp(s, self.s_grid, self.t_grid))

    def state_at_s(self, s: float) -> np.ndarray:
        """Nominal state at arc length s; past the end, flown on along the last velocity."""
        if s <= self.length_m:
            return self.plan.nominal_state(s)
        x = self._x_end.copy()
        x[:3] += (s - self.length_m) * self._dir_end
        return x

    def input_at_s(self, s: float) -> np.ndarray:
        """Nominal input at s, linear between the plan's nodes (the last one past the end)."""
        if s >= self._s1:
            return self._u_end.copy()
        p = self.plan
        i = int(np.clip(np.searchsorted(p.s, s) - 1, 0, len(p.s) - 2))
        a = min(max((s - p.s[i]) / (p.s[i + 1] - p.s[i]), 0.0), 1.0)
        return p.u[i] + a * (p.u[i + 1] - p.u[i])

    def reference(self, t: float) -> Reference:
        """State, input and accelerations of the reference at time ``t``."""
        s = self.s_at(float(t))
        x = self.state_at_s(s)
        u = self.input_at_s(s)
        dx = self.model.f(x, u)
        R = rpy_to_matrix(*x[3:6])
        acc = R @ (dx[6:9] + cross3(x[9:12], x[6:9]))
        return Reference(float(t), s, x, u, acc, dx[9:12])
