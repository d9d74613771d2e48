r"""The RK4 step loop of the backward Riccati sweep, compiled by numba where available.

The loop is sequential (each step starts from the last), so it cannot be vectorized across
nodes. It comes in two forms with the same maths and signature, and
:data:`mavreg.control.design.riccati.rk4_sweep` is the one that suits the path in use
(:mod:`mavreg.accel`):

- :func:`mavreg.control.design.riccati.rk4_sweep_numpy`, the reference: each step ~30 small
  (n x n) numpy operations, in plain Python (``MAVREG_PURE=1`` or no numba);
- :func:`rk4_sweep_loops` (here), compiled: the same products as explicit loops into buffers
  allocated once, the symmetric :math:`P S P` on one triangle. Compiled, numpy's small
  matrix products cost more in dispatch and allocation than in arithmetic (3.3 µs per
  right-hand side at n = 11, against about 1 µs as loops); in plain Python the loops would
  be two orders slower, hence two forms.

``tests/unit/test_plan_speed.py`` holds the two to round-off (a plan's gains, compiled
against pure); the maths and its checks are in :func:`mavreg.control.design.riccati.sweep_backward`.
"""
from __future__ import annotations

import numpy as np

from ...accel import njit

__all__ = ["rk4_sweep_loops"]


@njit
def _rhs_into(At, S, Q, P, AtP, SP, out):
    """``out = F(P)`` (:func:`rhs_transposed`) by loops; ``AtP``, ``SP``: (n, n) scratch."""
    n = P.shape[0]
    for i in range(n):
        for j in range(n):
            a = 0.0
            b = 0.0
            for m in range(n):
                pmj = P[m, j]
                a += At[i, m] * pmj
                b += S[i, m] * pmj
            AtP[i, j] = a
            SP[i, j] = b
    for i in range(n):
        for j in range(i, n):
            c = 0.0
            for m in range(n):
                c += P[i, m] * SP[m, j]
            v = AtP[i, j] + AtP[j, i] - c + Q[i, j]
            out[i, j] = v
            out[j, i] = v


@njit
def _axpy_into(X, h, Y, out):
    """``out = X + h Y`` elementwise on (n, n)."""
    n = X.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = X[i, j] + h * Y[i, j]


@njit
def rk4_sweep_loops(At_nodes, S_nodes, At_mid, S_mid, steps, Q, P_terminal, limit, P):
    """:func:`~mavreg.control.design.riccati.rk4_sweep_numpy` by loops into buffers allocated once (the compiled form)."""
    N, n = At_nodes.shape[0], At_nodes.shape[1]
    P[N - 1] = P_terminal
    k1 = np.empty((n, n))
    k2 = np.empty((n, n))
    k3 = np.empty((n, n))
    k4 = np.empty((n, n))
    X = np.empty((n, n))
    AtP = np.empty((n, n))
    SP = np.empty((n, n))
    for k in range(N - 2, -1, -1):
        hk = steps[k]
        Pk1 = P[k + 1]
        _rhs_into(At_nodes[k + 1], S_nodes[k + 1], Q, Pk1, AtP, SP, k1)
        _axpy_into(Pk1, 0.5 * hk, k1, X)
        _rhs_into(At_mid[k], S_mid[k], Q, X, AtP, SP, k2)
        _axpy_into(Pk1, 0.5 * hk, k2, X)
        _rhs_into(At_mid[k], S_mid[k], Q, X, AtP, SP, k3)
        _axpy_into(Pk1, hk, k3, X)
        _rhs_into(At_nodes[k], S_nodes[k], Q, X, AtP, SP, k4)
        Pk = P[k]
        c = hk / 6.0
        peak = 0.0
        finite = True
        for i in range(n):
            for j in range(i, n):
                a = Pk1[i, j] + c * (k1[i, j] + 2.0 * (k2[i, j] + k3[i, j]) + k4[i, j])
                b = Pk1[j, i] + c * (k1[j, i] + 2.0 * (k2[j, i] + k3[j, i]) + k4[j, i])
                v = 0.5 * (a + b)
                Pk[i, j] = v
                Pk[j, i] = v
                av = abs(v)
                if av > peak:
                    peak = av
                elif not av <= peak:      # NaN
                    finite = False
        if not finite or not np.isfinite(peak):
            return k, 1, np.nan if not finite else peak
        if peak > limit:
            return k, 2, peak
    return -1, 0, 0.0

