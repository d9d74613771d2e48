r"""Arc length of the nearest point on the path: local, warm-started, continuous in time.

:math:`s = \arg\min_\sigma |y - c(\sigma)|^2` (paper eq 21's :math:`\phi_1`) is found by
Newton's method on :math:`g(\sigma) = t(\sigma)^T (y - c(\sigma)) = 0`, with
:math:`g' = K^T (y - c) - 1` (K the curvature vector), started from the previous answer.
Each answer stays within ``window_m`` of the previous one, so on a closed, multi-lap or
self-approaching path s never jumps to another lap or another branch that happens to
pass close by: it follows the vehicle along the maneuver. The path goes on straight
before its start and after its end.

The nearest point is unique (and Newton converges) while the vehicle is inside the tube
where :math:`1 - K^T d > 0`, d the offset from the path: within the local radius of
curvature on the inside of a turn. :class:`Projection` says when the vehicle is outside
(with margin ``tube_margin``), or when the answer hit the window.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..accel import use_compiled
from .path import Path, PathPoint
from .projection_kernel import path_tables, project_series

__all__ = ["Projector", "Projection"]


@dataclass(frozen=True)
class Projection:
    s: float
    """Arc length of the nearest point (may be < 0 or > length: the straight extensions)."""
    distance_m: float
    in_tube: bool
    """False when the nearest point is not locally unique or the search hit its window."""
    point: PathPoint
    """The path's geometry at s."""


class Projector:
    """Warm-started nearest-point search on one path.

    Parameters
    ----------
    path : Path
    window_m : float
        Largest change of s in one update: well under a lap, well over what the vehicle
        travels between two updates.
    tube_margin : float
        ``1 - K.d`` below this is reported outside the tube (0 is the focal point).
    """

    def __init__(self, path: Path, window_m: float = 2.0, tube_margin: float = 0.25):
        self.path = path
        self.window_m = float(window_m)
        self.tube_margin = float(tube_margin)
        self.s = 0.0

    def reset(self, position, s_guess: float = 0.0) -> Projection:
        """Start from a global search, preferring the candidate nearest ``s_guess``.

        Among the path nodes within 5 cm of the closest distance, the one whose arc length
        is nearest ``s_guess`` wins; Newton then refines it.
        """
        y = np.asarray(position, dtype=float)
        self._start(y, s_guess)
        return self.update(y)

    def _start(self, y: np.ndarray, s_guess: float) -> None:
        """The warm start of :meth:`reset`: the path node nearest ``y`` (see there)."""
        d = np.linalg.norm(self.path.c_nodes - y, axis=1)
        near = np.flatnonzero(d <= d.min() + 0.05)
        j = near[np.argmin(np.abs(self.path.s_nodes[near] - s_guess))]
        self.s = float(self.path.s_nodes[j])

    def series(self, positions, s_guess: float = 0.0,
               compiled: bool | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Arc lengths and distances (K,) of ``positions`` (K, 3) in time order: :meth:`reset`
        on the first (preferring ``s_guess``), :meth:`update` on each next, as one compiled
        loop (:func:`~mavreg.geometry.projection_kernel.project_series`; where numba is not in
        use, or ``compiled=False``, these methods in turn). The warm start is left at the last
        answer."""
        pts = np.ascontiguousarray(positions, dtype=float).reshape(-1, 3)
        s_out, d_out = np.empty(len(pts)), np.empty(len(pts))
        if not len(pts):
            return s_out, d_out
        if not use_compiled(compiled, "projection"):
            for k, p in enumerate(pts):
                pr = self.reset(p, s_guess) if k == 0 else self.update(p)
                s_out[k], d_out[k] = pr.s, pr.distance_m
            return s_out, d_out
        self._start(pts[0], s_guess)
        project_series(pts, self.s, self.window_m, self.tube_margin, *path_tables(self.path), s_out, d_out)
        self.s = float(s_out[-1])
        return s_out, d_out

    def update(self, position) -> Projection:
        """Project ``position``; the answer becomes the next warm start."""
        y = np.asarray(position, dtype=float)
        s0 = self.s
        lo, hi = s0 - self.window_m, s0 + self.window_m
        s = s0
        ok = False
        p = self.path.point(s)
        for _ in range(12):
            d = y - p.position
            g = p.frame[:, 0] @ d
            dg = p.curvature_vector @ d - 1.0
            if dg > -1e-3:   # at or past the focal point: Newton is not a descent
                break
            step = float(np.clip(-g / dg, -0.5, 0.5))
            s_new = min(max(s + step, lo), hi)
            converged = abs(s_new - s) < 1e-9
            s = s_new
            p = self.path.point(s)
            if converged:
                ok = True
                break
        d = y - p.position
        inside = ok and (1.0 - p.curvature_vector @ d) > self.tube_margin and lo < s < hi
        self.s = s
        return Projection(s, float(np.linalg.norm(d)), bool(inside), p)
