r"""The speed governor: the speed profile re-timed from where the vehicle is.

Maneuver regulation schedules on the arc length s, so a vehicle held back by a gust is not
pulled towards a timed reference; but the paper's LQR still regulates the body velocity to
the profile's :math:`\bar v(s)`, and a large along-track deficit makes it tilt hard to win
the *speed* back, which throws it off the path (an 8 N gust on the barrel roll's run-up:
55 cm). The governor gives the regulator a speed to regulate to instead (docs/governor.md).

The governed speed
------------------
:math:`v_g` follows a target :math:`v_t = \min(\bar v, v_{cap})`: the profile, capped where
the rotors cannot give the thrust (:func:`thrust_speed_cap`). It is a state integrated in s,
not in time: from one control step to the next (:math:`\Delta s`), below the target,

.. math::
    v_g^2 \leftarrow v_g^2 + 2\,a_g\,\Delta s,\qquad
    a_g = \sigma^2 a_t + \min\Big(a_r,\ \frac{v_t - v_g}{\tau_r}\Big),\qquad
    \sigma = v_g / v_t,\qquad v_g \le v_t,

with :math:`a_t = v_t v_t'` the target's along-track acceleration: a vehicle slower than the
target keeps the target's speed *shape* (the same accelerations per metre, scaled by
:math:`\sigma^2`; at a constant :math:`\sigma` the whole acceleration vector, centripetal
included, is the nominal's times :math:`\sigma^2`), and the deficit closes at :math:`a_r`
(``recovery_accel_m_s2``), the last of it over :math:`\tau_r` (``recovery_time_constant_s``).
Whenever the vehicle's speed along the path :math:`v_\parallel = t^T \dot p` falls more than
the band :math:`\delta` below :math:`v_g`, the governed speed drops to
:math:`v_g = \max(v_\parallel + \delta, 0)`: the profile is re-timed from where the vehicle
is. So :math:`0 \le v_g \le \bar v(s)`: the governor never asks for more than the profile (no
catch-up) nor for going backwards, and a vehicle that does not progress is not asked to go
faster (s does not advance).

The reference
-------------
The regulator regulates to :math:`v_r = \min(v_g, v_\parallel + \delta)`: the along-track
deficit the LQR sees is never more than :math:`\delta`. What lies beyond (a vehicle pushed
backwards: :math:`v_g = 0 > v_\parallel + \delta`) is asked for as an along-track acceleration
:math:`k_v (v_g - v_r)` bounded by ``max_accel_m_s2``. Both accelerations reach the vehicle
through the nominal's thrust vector, not through the LQR: :func:`retiming_force` is what the
nominal thrust must add for the path flown at :math:`(v_r, a)` instead of
:math:`(\bar v, \bar v \bar v')`, and the regulator turns and scales the nominal thrust by it
(:func:`~mavreg.control.estimation.disturbance.compensate`). Pure.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...config.regulation import SpeedGovernorParams
from ...model.rotation import rpy_to_matrix

__all__ = ["GovernedSpeed", "SpeedGovernor", "thrust_speed_cap", "retiming_force", "along_track_speed"]


@dataclass(frozen=True)
class GovernedSpeed:
    speed_m_s: float
    """:math:`v_g(s)`."""
    accel_m_s2: float
    r""":math:`a_g`, the along-track acceleration the governed speed asks for."""
    retimed: bool
    """:math:`v_g` or :math:`a_g` differs from the plan's profile at s."""


def along_track_speed(tangent, velocity_ned) -> float:
    r"""The vehicle's speed along the path, :math:`t^T \dot p`: what the nominal's speed is
    compared with (the rate of s is this over :math:`1 - k^T w`, faster outside a turn)."""
    return float(np.asarray(tangent, dtype=float) @ np.asarray(velocity_ned, dtype=float))


def retiming_force(mass_kg: float, tangent, curvature_vector, profile_speed_m_s: float,
                   profile_accel_m_s2: float, speed_m_s: float, accel_m_s2: float,
                   drag_delta_n=None) -> np.ndarray:
    r"""The force :math:`d` (NED, N) by which the nominal thrust vector :math:`\bar T \bar R e_3`
    must change for the path flown at speed :math:`v_g` with along-track acceleration
    :math:`a_g` instead of the profile's :math:`(\bar v, \bar a)`:

    .. math::
        T_g R_g e_3 = \bar T \bar R e_3 + d,\qquad
        d = m\,[(\bar a - a_g)\,t + (\bar v^2 - v_g^2)\,K] + \Delta D,

    from :math:`m\ddot p = m g e_3 - T R e_3 + D` and :math:`\ddot p = a\,t + v^2 K` (K the
    curvature vector); :math:`\Delta D` is the change of the modelled drag (default none).
    """
    d = mass_kg * ((profile_accel_m_s2 - accel_m_s2) * np.asarray(tangent, dtype=float)
                   + (profile_speed_m_s ** 2 - speed_m_s ** 2) * np.asarray(curvature_vector, dtype=float))
    return d if drag_delta_n is None else d + np.asarray(drag_delta_n, dtype=float)


def thrust_speed_cap(plan, max_thrust_n: float, accel_m_s2: float) -> np.ndarray:
    r"""The speed on each node of ``plan.s`` at which the plan's nominal, re-timed by a ratio
    :math:`\sigma \le 1`, needs a thrust of at most ``max_thrust_n``, lowered ahead of a capped
    stretch so that it is reached slowing down at ``accel_m_s2`` at most (the governed speed
    returns to the profile after it at its own recovery, :class:`SpeedGovernor`).

    Flown at :math:`\sigma\bar v(s)` (the same speed shape, :math:`\sigma` constant), the
    acceleration is :math:`\sigma^2 \bar a` with :math:`\bar a = \bar v\bar v' t + \bar v^2 K`
    the nominal's (K the curvature vector), so the thrust is :math:`|G - m\sigma^2\bar a|` with
    :math:`G = \bar T\bar b_3 + m\bar a` (gravity and drag, as the nominal feeds them). The
    ratio is the larger root in :math:`\sigma^2 \le 1` of :math:`|G - m\sigma^2\bar a| = T_{max}`;
    where no ratio keeps the thrust under the limit, the one that needs the least. A change of
    :math:`\sigma` adds :math:`\bar v^2\,d(\sigma^2/2)/ds` of along-track acceleration: a backward
    pass bounds the slowing down by ``accel_m_s2``. Where the nominal needs no more than the
    limit, the result is the profile itself.
    """
    s = np.asarray(plan.s, dtype=float)
    m = float(plan.vehicle.mass_kg)
    _, F, k, _, _ = plan.path.evaluate(s)
    t = F[:, :, 0]
    K = k[:, 0:1] * F[:, :, 1] + k[:, 1:2] * F[:, :, 2]
    v = np.asarray(plan.speed_m_s, dtype=float)
    acc = np.gradient(0.5 * v * v, s)[:, None] * t + (v * v)[:, None] * K
    b3 = np.moveaxis(rpy_to_matrix(*plan.x[:, 3:6].T), -1, 0)[:, :, 2]
    G = plan.u[:, 0:1] * b3 + m * acc
    A = m * m * np.sum(acc * acc, axis=1)
    B = -2.0 * m * np.sum(G * acc, axis=1)
    C = np.sum(G * G, axis=1) - max_thrust_n ** 2
    r2 = np.ones(len(s))
    over = (A > 0.0) & (A + B + C > 0.0)             # the nominal itself needs more than the limit
    disc = B * B - 4.0 * A * C
    ok = over & (disc >= 0.0)
    r2[ok] = (-B[ok] + np.sqrt(disc[ok])) / (2.0 * A[ok])
    bad = over & (disc < 0.0)
    r2[bad] = -B[bad] / (2.0 * A[bad])
    r2 = np.clip(r2, 0.0, 1.0)
    step = 2.0 * accel_m_s2 * np.diff(s) / (v[:-1] * v[:-1])
    for i in range(len(s) - 2, -1, -1):          # slow down ahead of a capped stretch
        r2[i] = min(r2[i], r2[i + 1] + step[i])
    return np.sqrt(r2) * v


_ON_TARGET_M_S = 0.01
"""A governed speed this close below the target is the target (the reference's step then is
a hundredth of the band)."""


class SpeedGovernor:
    r""":math:`v_g` of the module docstring, updated once per control step.

    Parameters
    ----------
    s_nodes, profile_speed_m_s : (N,) arrays
        The plan's grid and speed profile :math:`\bar v`.
    params : SpeedGovernorParams
    speed_cap_m_s : (N,) array, optional
        :func:`thrust_speed_cap` on the same grid; None: no cap.
    """

    def __init__(self, s_nodes, profile_speed_m_s, params: SpeedGovernorParams, speed_cap_m_s=None):
        self._s = np.asarray(s_nodes, dtype=float)
        self._profile = np.asarray(profile_speed_m_s, dtype=float)
        target = self._profile if speed_cap_m_s is None else np.minimum(self._profile, speed_cap_m_s)
        self._capped = bool(np.any(target < self._profile))
        """The cap lowers the target somewhere."""
        self.target_m_s = target
        self._target_accel = np.gradient(0.5 * target * target, self._s)
        self._profile_accel = np.gradient(0.5 * self._profile ** 2, self._s)
        self._accel = float(params.recovery_accel_m_s2)
        self._tau = float(params.recovery_time_constant_s)
        self._band = float(params.speed_band_m_s)
        self._gain = float(params.speed_gain_per_s)
        self._max_accel = float(params.max_accel_m_s2)
        self._v: float | None = None
        """The governed speed at ``self._s_last``; None before the first update."""
        self._s_last = 0.0

    def reset(self) -> None:
        """The governed speed becomes the target's at the next update."""
        self._v = None

    def profile(self, s: float) -> tuple[float, float]:
        r"""The plan's :math:`(\bar v(s), \bar v \bar v'(s))` (clamped to the grid's ends)."""
        return (float(np.interp(s, self._s, self._profile)), float(np.interp(s, self._s, self._profile_accel)))

    def target(self, s: float) -> tuple[float, float]:
        """:math:`(v_t(s), v_t v_t'(s))`."""
        return (float(np.interp(s, self._s, self.target_m_s)), float(np.interp(s, self._s, self._target_accel)))

    def _accel_towards(self, s: float, v: float) -> float:
        r"""The along-track acceleration of a governed speed v below the target at s: the
        target's own scaled by :math:`\sigma^2 = (v/v_t)^2` (the same shape in s, at the lower
        speed), plus the deficit closed at ``recovery_accel_m_s2``, the last of it over
        ``recovery_time_constant_s``."""
        vt, at = self.target(s)
        gap = vt - v
        x = gap / self._tau if self._tau > 0.0 else (self._accel if gap > 0.0 else 0.0)
        sigma2 = (v / vt) ** 2 if vt > 0.0 else 0.0
        return sigma2 * at + min(max(x, 0.0), self._accel)

    def update(self, s: float, along_track_speed_m_s: float) -> GovernedSpeed:
        """Advance :math:`v_g` to s for a vehicle whose along-track speed is
        ``along_track_speed_m_s``; :math:`v_g` and its along-track acceleration
        :math:`a_g` there. Within ``_ON_TARGET_M_S`` of the target, :math:`v_g` is the
        target (and, uncapped, the plan's nominal is flown as it is)."""
        vt, at = self.target(s)
        v = vt
        if self._v is not None:
            vt_last = float(np.interp(self._s_last, self._s, self.target_m_s))
            if self._v < vt_last:
                a = self._accel_towards(self._s_last, self._v)
                v = min(math.sqrt(max(self._v * self._v + 2.0 * a * (s - self._s_last), 0.0)), vt)
                if vt - v < _ON_TARGET_M_S:
                    v = vt
        if along_track_speed_m_s < v - self._band:
            v = max(along_track_speed_m_s + self._band, 0.0)
        self._v, self._s_last = v, float(s)
        if v == vt and not self._capped:
            return GovernedSpeed(v, at, False)
        vp, ap = self.profile(s)
        a = at if v == vt else self._accel_towards(s, v)
        return GovernedSpeed(v, a, v != vp or a != ap)

    def reference(self, s: float, along_track_speed_m_s: float) -> tuple[GovernedSpeed, float]:
        r"""What the regulator regulates to at s: :math:`v_r = \min(v_g, v_\parallel + \delta)`
        with the governed acceleration (:meth:`update`), and the push
        :math:`\mathrm{sat}(k_v (v_g - v_r))` (m/s^2) for what lies beyond the band."""
        g = self.update(s, along_track_speed_m_s)
        v = min(g.speed_m_s, along_track_speed_m_s + self._band)
        if v == g.speed_m_s:
            return g, 0.0
        return GovernedSpeed(v, g.accel_m_s2, True), min(self._gain * (g.speed_m_s - v), self._max_accel)
