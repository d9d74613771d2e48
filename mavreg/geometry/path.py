r"""An arc-length parametrized path with a rotation-minimizing frame.

The path integrates the frame equations of :mod:`mavreg.geometry.segments` with classical
RK4 on a grid of arc length (a few millimetres, with nodes on every segment boundary), and
interpolates between nodes by
cubic Hermite polynomials using the exact derivatives :math:`c' = t`,
:math:`t' = k_1 m_1 + k_2 m_2`, :math:`m_i' = -k_i t`. Position errors are :math:`O(h^4)`:
nanometres at the default spacing. Before ``s = 0`` and after ``s = length`` the path goes
on as straight lines along its end tangents, so the projection is defined there too.

Evaluation at one ``s`` costs a few microseconds and allocates only small arrays.
"""
from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np


__all__ = ["Path", "PathPoint", "SegmentSpan"]


@dataclass(frozen=True)
class SegmentSpan:
    """A named stretch of the path, [s_start, s_end) in metres."""

    name: str
    kind: str
    s_start_m: float
    s_end_m: float


@dataclass(frozen=True)
class PathPoint:
    """Geometry at one arc length.

    ``frame`` has columns (t, m1, m2); ``k``, ``dk``, ``ddk`` are the RMF curvature
    components and their first and second derivatives in s.
    """

    s: float
    position: np.ndarray
    frame: np.ndarray
    k: np.ndarray
    dk: np.ndarray
    ddk: np.ndarray

    @property
    def curvature_vector(self) -> np.ndarray:
        """K = k1 m1 + k2 m2 = dt/ds (world frame)."""
        return self.frame[:, 1] * self.k[0] + self.frame[:, 2] * self.k[1]

    @property
    def curvature(self) -> float:
        return float(np.hypot(*self.k))

    @property
    def torsion(self) -> float:
        """Serret-Frenet torsion (k1 k2' - k2 k1') / kappa^2; 0 where kappa = 0."""
        k2 = self.k @ self.k
        if k2 < 1e-18:
            return 0.0
        return float((self.k[0] * self.dk[1] - self.k[1] * self.dk[0]) / k2)


def _frame_matrices(k: np.ndarray) -> np.ndarray:
    """M(k) (N, 4, 4) with d/ds (c, t, m1, m2) = M (c, t, m1, m2), rows stacked."""
    M = np.zeros((len(k), 4, 4))
    M[:, 0, 1] = 1.0
    M[:, 1, 2], M[:, 1, 3] = k[:, 0], k[:, 1]
    M[:, 2, 1], M[:, 3, 1] = -k[:, 0], -k[:, 1]
    return M


def _rk4_transitions(h: np.ndarray, k_start: np.ndarray, k_mid: np.ndarray,
                     k_end: np.ndarray) -> np.ndarray:
    """The classical RK4 step of the linear frame equations over each interval, as a matrix.

    RK4 applied to ``y' = M(s) y`` is linear in y: ``y_{i+1} = Phi_i y_i`` with
    ``Phi = I + h/6 (M_a + 2 B + 2 C + D)``, ``B = M_m (I + h/2 M_a)``,
    ``C = M_m (I + h/2 B)``, ``D = M_b (I + h C)`` (M at the start, middle and end of the
    interval). All intervals at once; only the chaining of the steps stays sequential.
    """
    hh = h[:, None, None]
    Ma, Mm, Mb = _frame_matrices(k_start), _frame_matrices(k_mid), _frame_matrices(k_end)
    B = Mm + hh / 2 * (Mm @ Ma)
    C = Mm + hh / 2 * (Mm @ B)
    D = Mb + hh * (Mb @ C)
    return np.eye(4) + hh / 6 * (Ma + 2 * B + 2 * C + D)


class Path:
    """A path built from curvature pieces and a start pose.

    Parameters
    ----------
    pieces : sequence of CurvaturePiece
        The segments in order (blends included).
    start_position : (3,) array
        NED position of s = 0.
    start_frame : (3, 3) array
        Columns (t, m1, m2): orthonormal, right-handed, t the start tangent.
    spacing_m : float
        Target grid spacing of the tabulation.
    """

    def __init__(self, pieces, start_position, start_frame, spacing_m: float = 0.005):
        self.pieces = tuple(pieces)
        if not self.pieces:
            raise ValueError("a path needs at least one segment")
        bounds = np.concatenate([[0.0], np.cumsum([p.length_m for p in self.pieces])])
        self.length_m = float(bounds[-1])
        self.spans = tuple(SegmentSpan(p.name, p.kind, float(a), float(b))
                           for p, a, b in zip(self.pieces, bounds[:-1], bounds[1:]))
        self._bounds = bounds
        # Nodes fall on every piece boundary, so no RK4 step straddles a change of piece
        # (where curvature may have a kink, or jump in a path the planner would reject).
        nodes, owner = [np.zeros(1)], []
        for j, piece in enumerate(self.pieces):
            m = max(1, int(np.ceil(piece.length_m / spacing_m)))
            nodes.append(bounds[j] + piece.length_m * np.arange(1, m + 1) / m)
            owner.append(np.full(m, j))
        self.s_nodes = np.concatenate(nodes)
        self.s_nodes[-1] = self.length_m
        self._s_list = self.s_nodes.tolist()
        owner = np.concatenate(owner)
        hs = np.diff(self.s_nodes)
        # Curvature at both ends and the middle of every interval, from its own piece.
        ends = [self._eval_owned(self.s_nodes[:-1], owner), self._eval_owned(self.s_nodes[1:], owner)]
        k_mid = self._eval_owned(self.s_nodes[:-1] + hs / 2, owner)[0]
        n = len(self.s_nodes)
        self.k_nodes = np.concatenate([ends[0][0], ends[1][0][-1:]])
        self.dk_nodes = np.concatenate([ends[0][1], ends[1][1][-1:]])
        self.ddk_nodes = np.concatenate([ends[0][2], ends[1][2][-1:]])
        F = np.asarray(start_frame, dtype=float)
        states = np.empty((n, 4, 3))
        states[0] = np.stack([np.asarray(start_position, float), F[:, 0], F[:, 1], F[:, 2]])
        steps = _rk4_transitions(hs, ends[0][0], k_mid, ends[1][0])
        for i in range(n - 1):
            states[i + 1] = steps[i] @ states[i]
        self.c_nodes = states[:, 0].copy()
        # Columns (t, m1, m2) per node, re-orthonormalized against slow drift.
        frames = np.transpose(states[:, 1:], (0, 2, 1))
        u, _, vt = np.linalg.svd(frames)
        self.frame_nodes = u @ vt
        self.closed = bool(np.linalg.norm(self.c_nodes[-1] - self.c_nodes[0]) < 1e-6)
        self._coef = self._hermite_table(hs, ends)

    def _hermite_table(self, hs: np.ndarray, ends) -> np.ndarray:
        """Cubic coefficients in u = (s - s_i)/h_i of everything :meth:`point` returns.

        Per interval, 18 values (c, F row-major, k, dk, ddk) as a0 + a1 u + a2 u^2 + a3 u^3:
        Hermite from the node values and the exact derivatives (c' = t, F' = F Omega(k),
        k' = dk, dk' = ddk), with the interval's own piece at both ends; ddk, piecewise
        linear, is the cubic with its own slope.
        """
        F = self.frame_nodes
        m = len(hs)

        def pack(Fn, cn, k, dk, ddk):
            val = np.concatenate([cn, Fn.reshape(m, 9), k, dk, ddk], axis=1)
            der = np.concatenate([Fn[:, :, 0], _frame_derivative(Fn, k).reshape(m, 9), dk, ddk,
                                  np.zeros((m, 2))], axis=1)
            return val, der

        p0, d0 = pack(F[:-1], self.c_nodes[:-1], *ends[0])
        p1, d1 = pack(F[1:], self.c_nodes[1:], *ends[1])
        m0, m1 = hs[:, None] * d0, hs[:, None] * d1
        slope = p1[:, 16:] - p0[:, 16:]
        m0[:, 16:], m1[:, 16:] = slope, slope
        return np.stack([p0, m0, 3 * (p1 - p0) - 2 * m0 - m1, 2 * (p0 - p1) + m0 + m1], axis=1)

    def __getstate__(self):
        # The pieces hold closures and are needed only while building: a Path travels
        # between processes (the daemon plans in a worker) as its tables.
        state = dict(self.__dict__)
        state["pieces"] = None
        return state

    def _eval_owned(self, s: np.ndarray, idx: np.ndarray):
        """k, dk, ddk at arc lengths s, each from the piece ``idx`` names."""
        k = np.zeros((s.size, 2))
        dk = np.zeros((s.size, 2))
        ddk = np.zeros((s.size, 2))
        for j, piece in enumerate(self.pieces):
            sel = idx == j
            if np.any(sel):
                k[sel], dk[sel], ddk[sel] = piece.eval(s[sel] - self._bounds[j])
        return k, dk, ddk

    # ------------------------------------------------------------------ evaluation
    def segment_at(self, s: float) -> SegmentSpan:
        """The named segment containing s (clamped to the first and last)."""
        j = int(np.clip(np.searchsorted(self._bounds, s, side="right") - 1, 0, len(self.spans) - 1))
        return self.spans[j]

    def point(self, s: float) -> PathPoint:
        """Position, frame and curvature at arc length s (extended straight outside)."""
        s = float(s)
        if s <= 0.0 or s >= self.length_m:
            i = 0 if s <= 0.0 else -1
            ref = 0.0 if s <= 0.0 else self.length_m
            F = self.frame_nodes[i]
            z = np.zeros(2)
            return PathPoint(s, self.c_nodes[i] + (s - ref) * F[:, 0], F.copy(),
                             self.k_nodes[i] if s == ref else z,
                             self.dk_nodes[i] if s == ref else z,
                             self.ddk_nodes[i] if s == ref else z)
        i = min(bisect_right(self._s_list, s) - 1, len(self._s_list) - 2)
        s0 = self._s_list[i]
        u = (s - s0) / (self._s_list[i + 1] - s0)
        a = self._coef[i]
        v = a[0] + u * (a[1] + u * (a[2] + u * a[3]))
        return PathPoint(s, v[0:3], v[3:12].reshape(3, 3), v[12:14], v[14:16], v[16:18])

    def evaluate(self, s_values) -> tuple[np.ndarray, ...]:
        """Vectorized :meth:`point` for arc lengths inside [0, length].

        Returns positions (N, 3), frames (N, 3, 3) with columns (t, m1, m2), and the RMF
        curvature components k, dk, ddk, each (N, 2).
        """
        s = np.clip(np.asarray(s_values, dtype=float), 0.0, self.length_m)
        i = np.clip(np.searchsorted(self.s_nodes, s, side="right") - 1, 0, len(self.s_nodes) - 2)
        u = ((s - self.s_nodes[i]) / (self.s_nodes[i + 1] - self.s_nodes[i]))[:, None]
        a = self._coef[i]
        v = a[:, 0] + u * (a[:, 1] + u * (a[:, 2] + u * a[:, 3]))
        c, F = v[:, 0:3], v[:, 3:12].reshape(-1, 3, 3)
        k, dk, ddk = v[:, 12:14], v[:, 14:16], v[:, 16:18]
        return c, F, k, dk, ddk


def _frame_derivative(F: np.ndarray, k: np.ndarray) -> np.ndarray:
    """dF/ds = F @ [[0, -k1, -k2], [k1, 0, 0], [k2, 0, 0]] for stacks F (N,3,3), k (N,2)."""
    t, m1, m2 = F[:, :, 0], F[:, :, 1], F[:, :, 2]
    k1, k2 = k[:, 0:1], k[:, 1:2]
    return np.stack([k1 * m1 + k2 * m2, -k1 * t, -k2 * t], axis=2)
