r"""Speed and yaw profiles along arc length, smooth enough for the flatness map.

A profile starts at a value and changes by smooth steps, each from the value it finds to a
new one over a stretch of arc length. The step is the septic

.. math:: S(x) = 35x^4 - 84x^5 + 70x^6 - 20x^7,\qquad x\in[0,1],

whose first three derivatives vanish at both ends, so a profile is :math:`C^3`. Speed
enters the thrust through its first derivative, the body rates through its second and the
torques through its third; yaw enters the torques through its second. Hence the nominal
input is continuous.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Profile", "smooth_step"]

_C = np.array([35.0, -84.0, 70.0, -20.0])  # coefficients of x^4..x^7


def smooth_step(x: np.ndarray) -> np.ndarray:
    """S(x) and its first three derivatives, shape (4, N); x is clipped to [0, 1]."""
    x = np.clip(x, 0.0, 1.0)
    out = np.zeros((4,) + x.shape)
    for j, c in enumerate(_C):
        n = 4 + j
        out[0] += c * x ** n
        out[1] += c * n * x ** (n - 1)
        out[2] += c * n * (n - 1) * x ** (n - 2)
        out[3] += c * n * (n - 1) * (n - 2) * x ** (n - 3)
    return out


@dataclass(frozen=True)
class Profile:
    """A C3 profile: ``initial`` then steps ``(s_start, length, to_value)`` in order."""

    initial: float
    steps: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self):
        end = -np.inf
        for s0, length, _ in self.steps:
            if s0 < end - 1e-9:
                raise ValueError(f"profile changes overlap: one starts at s = {s0:.3f} m "
                                 f"before the previous ends at s = {end:.3f} m")
            end = s0 + length

    def evaluate(self, s) -> np.ndarray:
        """Value and its first three s-derivatives, shape (4, N)."""
        s = np.atleast_1d(np.asarray(s, dtype=float))
        out = np.zeros((4, s.size))
        out[0] = self.initial
        value = self.initial
        for s0, length, to in self.steps:
            S = smooth_step((s - s0) / length)
            delta = to - value
            for d in range(4):
                out[d] += delta * S[d] / length ** d
            value = to
        return out
