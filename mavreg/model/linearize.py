"""Complex-step Jacobians: derivatives to machine precision without subtractive cancellation.

For analytic f, ``f(x + i h e_j).imag / h`` equals ``df/dx_j`` to O(h^2) with no
round-off from a difference, so h can be 1e-30.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["complex_step_jacobian", "model_jacobians"]

_H = 1e-30


def complex_step_jacobian(fun: Callable[[np.ndarray], np.ndarray], z: np.ndarray) -> np.ndarray:
    """Jacobian d fun / d z at real ``z``; ``fun`` must accept complex arrays.

    ``z`` may be a batch of shape (..., n) with ``fun`` mapping (..., n) to (..., m) row by
    row; the result is then (..., m, n): every row is perturbed at once, one component
    at a time.
    """
    z = np.asarray(z, dtype=float)
    out = None
    for j in range(z.shape[-1]):
        dz = z.astype(complex)
        dz[..., j] += 1j * _H
        col = np.asarray(fun(dz)).imag / _H
        if out is None:
            out = np.empty(col.shape + (z.shape[-1],))
        out[..., j] = col
    return out


def model_jacobians(f: Callable, x: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) = (df/dx, df/du) of ``f(x, u)`` at (x, u)."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    A = complex_step_jacobian(lambda xc: f(xc, u.astype(complex)), x)
    B = complex_step_jacobian(lambda uc: f(x.astype(complex), uc), u)
    return A, B
