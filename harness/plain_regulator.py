r"""The baseline of the controller-step figure: the regulator step written the plain way.

:class:`PlainRegulator` computes what :meth:`mavreg.control.controllers.regulator.ManeuverRegulator.step`
computes for the paper's design (gains (4, 11), no disturbance compensation, no speed
governor, the paper's allocation), the straightforward way: every table is a
``scipy.interpolate.interp1d`` (the nominal x(s), u(s), v(s) and the gains K(s), linear,
held at the ends), the path's geometry a ``scipy.interpolate.PPoly`` of the path's own cubic
pieces (straight lines beyond its ends), and the projection, the transverse coordinates
and the allocation are small numpy arrays:

.. math::
    s = \arg\min_\sigma |p - c(\sigma)|, \qquad
    u = \bar u\big(s + v(s)\,\ell\big) - K(s)\,w(x, s), \qquad
    f = \mathrm{yaw\_then\_lift}(M^{-1}, u),

with the lead :math:`\ell = T/2 + \tau` (control period T, rotor lag tau). It agrees with the production
step to 1e-9 (``tests/unit/test_plain_regulator.py``); ``python -m benchmarks`` times both
on the same states.
"""
from __future__ import annotations

import numpy as np
from scipy.interpolate import PPoly, interp1d

from mavreg.control.design.transverse import transverse_coordinates
from mavreg.model.mixer import Mixer, yaw_then_lift

__all__ = ["PlainRegulator"]


def _table(s, values):
    """Linear interpolation of ``values`` (rows by s), held at the first and last rows."""
    return interp1d(s, values, axis=0, bounds_error=False, fill_value=(values[0], values[-1]), assume_sorted=True)


class PlainRegulator:
    """The paper's regulator step with scipy interpolators and small numpy arrays.

    Parameters
    ----------
    plan : mavreg.maneuver.plan.Plan
        With gains (4, 11).
    vehicle : mavreg.config.vehicle.VehicleParams
        For the mixer and the rotor limit.
    control_period_s : float
        The command's hold period T.
    rotor_time_constant_s : float, optional
        The rotors' lag tau (default: the vehicle's); the feedforward leads by T/2 + tau.
    window_m : float
        Largest change of s per step, as :class:`mavreg.geometry.projection.Projector`'s.
    """

    def __init__(self, plan, vehicle, control_period_s: float, rotor_time_constant_s: float | None = None,
                 window_m: float = 2.0):
        if plan.K.shape[-1] != 11:
            raise ValueError("the plain regulator is the paper's design: gains (4, 11)")
        path = plan.path
        h = np.diff(path.s_nodes)[:, None]
        a = path._coef                        # (M, 4, 18): cubic in u = (s - s_i) / h_i
        self._geometry = PPoly(np.stack([a[:, 3] / h ** 3, a[:, 2] / h ** 2, a[:, 1] / h, a[:, 0]]),
                               path.s_nodes, extrapolate=False)
        self._path = path
        self._x, self._u, self._K = _table(plan.s, plan.x), _table(plan.s, plan.u), _table(plan.s, plan.K)
        self._v = _table(plan.s, plan.speed_m_s)
        self._Minv = Mixer.from_vehicle(vehicle).inverse
        self._fmax = float(vehicle.max_rotor_thrust_n)
        tau = vehicle.rotor_time_constant_s if rotor_time_constant_s is None else rotor_time_constant_s
        self._lead_s = control_period_s / 2 + tau
        self._window = window_m
        self.s = 0.0

    def _point(self, s: float):
        """Position, frame (columns t, m1, m2) and (k1, k2) at s."""
        path = self._path
        if s <= 0.0 or s >= path.length_m:
            i, ref = (0, 0.0) if s <= 0.0 else (-1, path.length_m)
            F = path.frame_nodes[i]
            return path.c_nodes[i] + (s - ref) * F[:, 0], F, path.k_nodes[i] if s == ref else np.zeros(2)
        v = self._geometry(s)
        return v[0:3], v[3:12].reshape(3, 3), v[12:14]

    def reset(self, x) -> None:
        """Start from the path node nearest the position, then one projection."""
        d = np.linalg.norm(self._path.c_nodes - np.asarray(x[:3]), axis=1)
        near = np.flatnonzero(d <= d.min() + 0.05)
        self.s = float(self._path.s_nodes[near[np.argmin(np.abs(self._path.s_nodes[near]))]])
        self._project(np.asarray(x[:3], dtype=float))

    def _project(self, y):
        """Newton on t(s).(y - c(s)) = 0 from the last s, within the window."""
        lo, hi = self.s - self._window, self.s + self._window
        s = self.s
        c, F, k = self._point(s)
        for _ in range(12):
            d = y - c
            dg = (F[:, 1] * k[0] + F[:, 2] * k[1]) @ d - 1.0
            if dg > -1e-3:
                break
            s_new = min(max(s + float(np.clip(-(F[:, 0] @ d) / dg, -0.5, 0.5)), lo), hi)
            done = abs(s_new - s) < 1e-9
            s = s_new
            c, F, k = self._point(s)
            if done:
                break
        self.s = s
        return c, F

    def step(self, x) -> np.ndarray:
        """Rotor forces (4,) for state x (12,)."""
        x = np.asarray(x, dtype=float)
        c, F = self._project(x[:3])
        s = self.s
        xbar, K = self._x(s), self._K(s)
        ubar = self._u(s + float(self._v(s)) * self._lead_s)
        w = transverse_coordinates(x[:3], F, c, x, xbar)
        return yaw_then_lift(self._Minv, ubar - K @ w, self._fmax)
