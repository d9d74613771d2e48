r"""Path segments as curvature pieces in a rotation-minimizing frame.

A path is described intrinsically. Along arc length :math:`\sigma` it carries a
rotation-minimizing (Bishop) frame :math:`(t, m_1, m_2)` with

.. math::
    c' = t,\quad t' = k_1 m_1 + k_2 m_2,\quad m_1' = -k_1 t,\quad m_2' = -k_2 t,

so a segment is fully given by its length and its curvature components
:math:`k(\sigma) = (k_1, k_2)`. The curvature is :math:`\kappa = |k|`; where
:math:`\kappa > 0` the Serret-Frenet normal is :math:`n = k/\kappa` and the torsion is the
rate at which :math:`k` turns, :math:`\tau = (k_1 k_2' - k_2 k_1')/\kappa^2`. Where
:math:`\kappa = 0` the frame stays defined, which Serret-Frenet is not.

Each piece returns :math:`k, k', k''` (the flatness map needs snap, hence :math:`k''`).
A *blend* of length L is a quintic Hermite interpolation of :math:`(k, k', k'')` that
replaces the last L/2 of one piece and the first L/2 of the next, so curvature is
:math:`C^2` across the junction: finite, continuous torque, where a jump in curvature would
need an infinite one. Between a line and an arc the blend turns the tangent by exactly the
angle of the half-arc it replaces, so the headings of the lines around a blended loop are
those of the unblended path (the railway transition-curve construction).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CurvaturePiece", "line_piece", "arc_piece", "helix_piece", "blend_piece",
           "waypoint_piece"]


@dataclass(frozen=True)
class CurvaturePiece:
    """One segment of a path: its length and its RMF curvature components.

    ``coeffs`` is the piece's definition; :meth:`eval` returns arrays
    ``k, dk, ddk`` of shape (len(sigma), 2) for local arc lengths ``sigma`` in [0, length].
    """

    name: str
    kind: str
    length_m: float
    _eval: object  # callable sigma -> (k, dk, ddk)

    def eval(self, sigma) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        sigma = np.atleast_1d(np.asarray(sigma, dtype=float))
        return self._eval(sigma)

    def trimmed(self, start_m: float, end_m: float) -> "CurvaturePiece":
        """The same piece without its first ``start_m`` and last ``end_m`` metres."""
        if start_m == 0.0 and end_m == 0.0:
            return self
        length = self.length_m - start_m - end_m
        if length <= 0.0:
            raise ValueError(f"segment {self.name!r} ({self.length_m:.3f} m) is shorter than "
                             f"the blends that take {start_m + end_m:.3f} m of it")
        inner = self._eval
        return CurvaturePiece(self.name, self.kind, length, lambda sigma: inner(sigma + start_m))

    def start(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k, dk, ddk = self.eval([0.0])
        return k[0], dk[0], ddk[0]

    def end(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k, dk, ddk = self.eval([self.length_m])
        return k[0], dk[0], ddk[0]


def _const(k: np.ndarray):
    def ev(sigma):
        n = sigma.size
        return np.tile(k, (n, 1)), np.zeros((n, 2)), np.zeros((n, 2))
    return ev


def line_piece(name: str, length_m: float) -> CurvaturePiece:
    """A straight line: k = 0."""
    return CurvaturePiece(name, "line", float(length_m), _const(np.zeros(2)))


def arc_piece(name: str, radius_m: float, angle_rad: float, direction: np.ndarray) -> CurvaturePiece:
    """A circular arc of ``radius_m`` turning by ``angle_rad`` towards ``direction``.

    ``direction`` is the unit bend direction as RMF components (cos b, sin b).
    """
    k = np.asarray(direction, dtype=float) / radius_m
    return CurvaturePiece(name, "arc", float(radius_m * angle_rad), _const(k))


def helix_piece(name: str, radius_m: float, pitch_m: float, angle_rad: float,
                direction: np.ndarray) -> CurvaturePiece:
    r"""A circular helix: radius r, rise ``pitch_m`` per turn, ``angle_rad`` of turning.

    With :math:`c = p/2\pi`: :math:`\kappa = r/(r^2+c^2)`, :math:`\tau = c/(r^2+c^2)` and
    length :math:`\alpha\sqrt{r^2+c^2}`. The curvature vector starts along ``direction``
    and turns at rate :math:`\tau` about the tangent (right-handed for pitch > 0).
    """
    c = pitch_m / (2 * np.pi)
    rho2 = radius_m ** 2 + c ** 2
    kappa, tau = radius_m / rho2, c / rho2
    beta = float(np.arctan2(direction[1], direction[0]))

    def ev(sigma):
        a = beta + tau * sigma
        cs, sn = np.cos(a), np.sin(a)
        k = kappa * np.stack([cs, sn], axis=1)
        dk = kappa * tau * np.stack([-sn, cs], axis=1)
        ddk = -kappa * tau ** 2 * np.stack([cs, sn], axis=1)
        return k, dk, ddk

    return CurvaturePiece(name, "helix", float(angle_rad * np.sqrt(rho2)), ev)


def blend_piece(name: str, length_m: float, start, end) -> CurvaturePiece:
    """Quintic Hermite blend of (k, k', k'') from ``start`` to ``end`` over ``length_m``.

    ``start`` and ``end`` are triples (k, dk, ddk) of RMF components. Between a line and
    an arc this is the quintic "smootherstep" rise of curvature.
    """
    L = float(length_m)
    k0, d0, dd0 = (np.asarray(a, dtype=float) for a in start)
    k1, d1, dd1 = (np.asarray(a, dtype=float) for a in end)
    # Coefficients in u = sigma / L of a quintic with given value, slope, curvature at both ends.
    a0, a1, a2 = k0, d0 * L, dd0 * L * L / 2
    b = k1 - (a0 + a1 + a2)
    bd = d1 * L - (a1 + 2 * a2)
    bdd = dd1 * L * L - 2 * a2
    a3 = 10 * b - 4 * bd + bdd / 2
    a4 = -15 * b + 7 * bd - bdd
    a5 = 6 * b - 3 * bd + bdd / 2
    coef = np.stack([a0, a1, a2, a3, a4, a5])  # (6, 2)

    def ev(sigma):
        u = (sigma / L)[:, None]
        k = coef[0] + u * (coef[1] + u * (coef[2] + u * (coef[3] + u * (coef[4] + u * coef[5]))))
        dk = (coef[1] + u * (2 * coef[2] + u * (3 * coef[3] + u * (4 * coef[4] + u * 5 * coef[5])))) / L
        ddk = (2 * coef[2] + u * (6 * coef[3] + u * (12 * coef[4] + u * 20 * coef[5]))) / (L * L)
        return k, dk, ddk

    return CurvaturePiece(name, "blend", L, ev)


def waypoint_piece(name: str, points: np.ndarray, t0: np.ndarray, m1: np.ndarray,
                   samples_per_m: float = 400.0) -> tuple[CurvaturePiece, np.ndarray]:
    """A smooth curve from the origin through ``points`` (N x 3, relative to the start).

    A degree-7 interpolating spline in chord length, leaving along ``t0`` with zero
    curvature and zero curvature slope at both ends, so that it joins lines without a
    blend (and anything else through a blend). Its curvature, expressed in the RMF
    ``(t0, m1, m2)`` carried along it, is tabulated and splined, so the path integrator
    reproduces the curve. Returns the piece and the arc length at the start and at each
    waypoint.
    """
    pts = np.vstack([np.zeros(3), np.asarray(points, dtype=float)])
    chords = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    if np.any(chords < 1e-6):
        raise ValueError("waypoints must be distinct from each other and from the start")
    u = np.concatenate([[0.0], np.cumsum(chords)])
    if len(pts) < 3:
        raise ValueError("a waypoint curve needs at least two waypoints (use a line)")
    from scipy.interpolate import make_interp_spline   # waypoint curves only: 23 MB, 0.25 s
    zero = np.zeros(3)
    # End tangent: along the last chord; degree 7 takes three conditions at each end.
    t_end = (pts[-1] - pts[-2]) / chords[-1]
    spl = make_interp_spline(u, pts, k=7, bc_type=(
        [(1, t0), (2, zero), (3, zero)], [(1, t_end), (2, zero), (3, zero)]))
    # Arc length by dense quadrature of |p_u|.
    n = max(200, int(u[-1] * samples_per_m))
    uu = np.linspace(0.0, u[-1], n + 1)
    d1 = spl(uu, 1)
    speed = np.linalg.norm(d1, axis=1)
    if np.min(speed) < 1e-6:
        raise ValueError("waypoint curve has a cusp; move the waypoints apart")
    # Simpson's rule on each sub-interval.
    mid = np.linalg.norm(spl((uu[:-1] + uu[1:]) / 2, 1), axis=1)
    ds = np.diff(uu) * (speed[:-1] + 4 * mid + speed[1:]) / 6
    sig = np.concatenate([[0.0], np.cumsum(ds)])
    # Curvature vector p_ss = (p_uu - (t . p_uu) t) / |p_u|^2, then its RMF components.
    d2 = spl(uu, 2)
    t = d1 / speed[:, None]
    kvec = (d2 - np.sum(t * d2, axis=1)[:, None] * t) / speed[:, None] ** 2
    # Carry the RMF along (double reflection method, Wang et al. 2008).
    M1 = np.empty((n + 1, 3))
    M1[0] = m1
    pos = spl(uu)
    for i in range(n):
        v1 = pos[i + 1] - pos[i]
        c1 = v1 @ v1
        rL = M1[i] - (2 / c1) * (v1 @ M1[i]) * v1
        tL = t[i] - (2 / c1) * (v1 @ t[i]) * v1
        v2 = t[i + 1] - tL
        c2 = v2 @ v2
        M1[i + 1] = rL - (2 / c2) * (v2 @ rL) * v2 if c2 > 1e-30 else rL
    M2 = np.cross(t, M1)
    k = np.stack([np.sum(kvec * M1, axis=1), np.sum(kvec * M2, axis=1)], axis=1)
    k[0] = 0.0
    k[-1] = 0.0
    from scipy.interpolate import CubicSpline
    kspl = CubicSpline(sig, k, bc_type=((1, np.zeros(2)), (1, np.zeros(2))))

    def ev(sigma):
        s = np.clip(sigma, 0.0, sig[-1])
        return kspl(s), kspl(s, 1), kspl(s, 2)

    return CurvaturePiece(name, "waypoints", float(sig[-1]), ev), np.interp(u, uu, sig)
