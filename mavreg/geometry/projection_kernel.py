r"""The path's geometry at one arc length and the warm-started projection on it, as scalar
kernels that numba compiles (:func:`mavreg.accel.njit`).

The same maths as :meth:`mavreg.geometry.path.Path.point` and
:meth:`mavreg.geometry.projection.Projector.update`, on the path's own tables, step for step:

- :func:`path_point`: the cubic Hermite polynomial of the interval holding s,
  :math:`v = a_0 + u(a_1 + u(a_2 + u a_3))`, :math:`u = (s - s_i)/(s_{i+1} - s_i)`, 18 values
  (c, the frame (t, m1, m2) row-major, k, dk, ddk); before 0 and after the length the
  straight extension along the end tangent, with k, dk, ddk zero off the end itself;
- :func:`project_series`: :func:`project` of a sequence of positions, each warm-started from
  the answer before (what a flight's record needs, sample by sample);
- :func:`project`: Newton's method on :math:`g(\sigma) = t^T (y - c(\sigma)) = 0`,
  :math:`g' = K^T (y - c) - 1`, from the previous s, each step clipped to 0.5 m and the
  answer kept within the window around the previous s, at most :data:`MAX_ITERATIONS`
  iterations (two or three in tracking), stopping at a change below 1e-9 m; the tube test
  :math:`1 - K^T d >` margin, converged, strictly inside the window.

Only the dot products may round differently from numpy's (an ulp). :func:`path_tables`
lays the path out for them; the global search of :meth:`Projector.reset` stays in Python
(it runs once per maneuver).
"""
from __future__ import annotations

import numpy as np

from ..accel import njit
from .path import Path

__all__ = ["path_tables", "path_point", "project", "project_series", "MAX_ITERATIONS", "POINT_WIDTH"]

MAX_ITERATIONS = 12
"""Newton iterations per projection (as :meth:`~mavreg.geometry.projection.Projector.update`)."""
POINT_WIDTH = 18
"""Values per path point: c (0:3), frame row-major (3:12; t = 3, 6, 9), k (12:14), dk, ddk."""


def path_tables(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(s_nodes (M+1,), coef (M, 4, 18), ends (2, 18))`` of ``path``, C-contiguous: the
    nodes, the Hermite coefficients per interval and the 18 values at s = 0 and s = length
    (for the straight extensions)."""
    ends = np.empty((2, POINT_WIDTH))
    for row, i in enumerate((0, -1)):
        ends[row] = np.concatenate([path.c_nodes[i], path.frame_nodes[i].reshape(9),
                                    path.k_nodes[i], path.dk_nodes[i], path.ddk_nodes[i]])
    return (np.ascontiguousarray(path.s_nodes, dtype=float),
            np.ascontiguousarray(path._coef, dtype=float), ends)


@njit
def path_point(s, s_nodes, coef, ends, out):
    """Write the 18 values of the path at arc length ``s`` into ``out`` (see :data:`POINT_WIDTH`)."""
    n = s_nodes.shape[0]
    length = s_nodes[n - 1]
    if s <= 0.0 or s >= length:
        side = 0 if s <= 0.0 else 1
        ref = 0.0 if s <= 0.0 else length
        e = ends[side]
        for j in range(3):
            out[j] = e[j] + (s - ref) * e[3 + 3 * j]
        for j in range(3, 12):
            out[j] = e[j]
        for j in range(12, POINT_WIDTH):
            out[j] = e[j] if s == ref else 0.0
        return
    i = min(np.searchsorted(s_nodes, s, side="right") - 1, n - 2)
    s0 = s_nodes[i]
    u = (s - s0) / (s_nodes[i + 1] - s0)
    a = coef[i]
    for j in range(POINT_WIDTH):
        out[j] = a[0, j] + u * (a[1, j] + u * (a[2, j] + u * a[3, j]))


@njit
def _newton_terms(y0, y1, y2, p):
    """(g, g', offset) at the point ``p``: :math:`t^T d`, :math:`K^T d - 1`, d = y - c."""
    d0 = y0 - p[0]
    d1 = y1 - p[1]
    d2 = y2 - p[2]
    g = p[3] * d0 + p[6] * d1 + p[9] * d2
    kd = ((p[4] * p[12] + p[5] * p[13]) * d0 + (p[7] * p[12] + p[8] * p[13]) * d1
          + (p[10] * p[12] + p[11] * p[13]) * d2)
    return g, kd - 1.0, d0, d1, d2


@njit
def project(y0, y1, y2, s_prev, window_m, tube_margin, s_nodes, coef, ends, p):
    """Project the position (y0, y1, y2) from the previous answer ``s_prev``.

    Returns ``(s, in_tube, distance_m)`` and leaves the path's 18 values at s in ``p``.
    """
    lo = s_prev - window_m
    hi = s_prev + window_m
    s = s_prev
    ok = False
    path_point(s, s_nodes, coef, ends, p)
    for _ in range(MAX_ITERATIONS):
        g, dg, _, _, _ = _newton_terms(y0, y1, y2, p)
        if dg > -1e-3:      # at or past the focal point: Newton is not a descent
            break
        step = min(max(-g / dg, -0.5), 0.5)
        s_new = min(max(s + step, lo), hi)
        converged = abs(s_new - s) < 1e-9
        s = s_new
        path_point(s, s_nodes, coef, ends, p)
        if converged:
            ok = True
            break
    _, dg, d0, d1, d2 = _newton_terms(y0, y1, y2, p)
    inside = ok and -dg > tube_margin and lo < s < hi
    return s, inside, np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit
def project_series(positions, s_start, window_m, tube_margin, s_nodes, coef, ends, s_out, distance_out):
    """:func:`project` each row of ``positions`` (K, 3) in turn, the first from ``s_start``,
    each next from the answer before; arc lengths into ``s_out`` (K,), distances into
    ``distance_out`` (K,)."""
    p = np.empty(POINT_WIDTH)
    s = s_start
    for k in range(positions.shape[0]):
        s, _, d = project(positions[k, 0], positions[k, 1], positions[k, 2], s, window_m, tube_margin,
                          s_nodes, coef, ends, p)
        s_out[k] = s
        distance_out[k] = d
