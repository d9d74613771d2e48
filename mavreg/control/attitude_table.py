"""The nominal attitude of a plan as the regulator reads it: rows of rotation matrices,
blended along the geodesic between neighbours.

The SO(3) form of the regulator needs Rbar(s) at the vehicle's s. The rows are a few
milliseconds of flight apart, so the geodesic between two rows is a turn of a few
milliradians; its rotation vector is computed once per row when the table is built, and a
step costs one Rodrigues formula: Rbar = R_i Exp(a d_i), d_i = Log(R_i^T R_{i+1}).
"""
from __future__ import annotations

import math

import numpy as np

from ..model.so3 import log_so3

__all__ = ["NominalAttitudes"]


class NominalAttitudes:
    """Rbar at a row ``i`` and a fraction ``a`` of the way to row ``i + 1``."""

    def __init__(self, R: np.ndarray):
        self.R = np.ascontiguousarray(R, dtype=float)
        self.turn = np.ascontiguousarray(log_so3(np.swapaxes(self.R[:-1], 1, 2) @ self.R[1:]))

    def at(self, i: int, a: float) -> np.ndarray:
        """R_i Exp(a d_i) (scalar Rodrigues: equal to :func:`~mavreg.model.so3.exp_so3`)."""
        x, y, z = (a * float(c) for c in self.turn[i])
        t2 = x * x + y * y + z * z
        if t2 < 1e-8:
            s, c = 1.0 - t2 / 6.0 + t2 * t2 / 120.0, 0.5 - t2 / 24.0 + t2 * t2 / 720.0
        else:
            th = math.sqrt(t2)
            s, c = math.sin(th) / th, (1.0 - math.cos(th)) / t2
        E = np.array([[1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y],
                      [c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x],
                      [c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y)]])
        return self.R[i] @ E
