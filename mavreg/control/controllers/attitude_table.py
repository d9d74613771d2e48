"""The nominal attitude of a plan between its rows: a cubic in the rotation vector.

The SO(3) form of the regulator needs Rbar(s) at the vehicle's s. Between rows i and i+1,
h apart in s, Rbar = R_i Exp(xi(a)), a = (s - s_i)/h, with xi the cubic Hermite polynomial
that starts at 0 with slope h w_i and ends at d_i = Log(R_i^T R_{i+1}) with slope h w_{i+1}
(w the nominal body rates per metre, omega/v): the attitude analogue of the Hermite
interpolation of the nominal state, O(h^3) where the geodesic alone (xi = a d_i) is O(h^2).
The end slope is the body rate of row i+1 in row i's frame to first order in |d_i|, a few
milliradians between rows. The rotation vectors are computed once per row; a step costs a
Rodrigues formula.
"""
from __future__ import annotations

import numpy as np

from ...model.rotation_kernel import rodrigues as _rodrigues9
from ...model.so3 import exp_so3, log_so3

__all__ = ["NominalAttitudes", "rodrigues"]


def rodrigues(x: float, y: float, z: float) -> np.ndarray:
    """Exp of the rotation vector (x, y, z) as a (3, 3) array (the compiled kernels' scalar
    Rodrigues, :func:`mavreg.model.rotation_kernel.rodrigues`)."""
    return np.array(_rodrigues9(x, y, z)).reshape(3, 3)


class NominalAttitudes:
    """Rbar at row ``i`` and fraction ``a`` towards row ``i + 1``.

    Parameters
    ----------
    s : (N,) arc lengths of the rows; R : (N, 3, 3) attitudes; rates_per_m : (N, 3) body
    rates over speed (rad/m).
    """

    def __init__(self, s, R, rates_per_m):
        self.R = np.ascontiguousarray(R, dtype=float)
        h = np.diff(np.asarray(s, dtype=float))[:, None]
        w = np.asarray(rates_per_m, dtype=float)
        self.d = log_so3(np.swapaxes(self.R[:-1], 1, 2) @ self.R[1:])
        self.m0 = h * w[:-1]
        self.m1 = h * w[1:]

    def at(self, i: int, a: float) -> np.ndarray:
        a2 = a * a
        a3 = a2 * a
        h10, h01, h11 = a3 - 2.0 * a2 + a, -2.0 * a3 + 3.0 * a2, a3 - a2
        xi = h10 * self.m0[i] + h01 * self.d[i] + h11 * self.m1[i]
        return self.R[i] @ rodrigues(float(xi[0]), float(xi[1]), float(xi[2]))

    def at_many(self, i, a) -> np.ndarray:
        """:meth:`at` for arrays of rows ``i`` (K,) and fractions ``a`` (K,): (K, 3, 3), by
        :func:`~mavreg.model.so3.exp_so3` (the same rotation as :meth:`at` to rounding)."""
        i = np.asarray(i, dtype=np.intp)
        a = np.asarray(a, dtype=float)[:, None]
        a2 = a * a
        a3 = a2 * a
        xi = (a3 - 2.0 * a2 + a) * self.m0[i] + (-2.0 * a3 + 3.0 * a2) * self.d[i] + (a3 - a2) * self.m1[i]
        return self.R[i] @ exp_so3(xi)
