r"""The RK4 step loop of the backward Riccati sweep, compiled by numba where available.

The loop is sequential (each step starts from the last), so it cannot be vectorized across
nodes; in numpy each of its ~30 small (n x n) operations per step costs more in dispatch than
in arithmetic. This module holds only the loop, in the numba-compilable subset of numpy, and
:func:`mavreg.accel.njit` compiles it or leaves it plain Python (the reference path). The
maths and its checks are in :func:`mavreg.control.riccati.sweep_backward`.
"""
from __future__ import annotations

import numpy as np

from ..accel import njit

__all__ = ["rk4_sweep", "rhs_transposed"]


@njit
def rhs_transposed(At, S, Q, P):
    r"""``F(P) = A^T P + P A - P S P + Q``, so that ``-P' = F``; ``At`` is ``A^T``, P
    symmetric (so that ``P A = (A^T P)^T``)."""
    AtP = At @ P
    return AtP + AtP.T - P @ (S @ P) + Q


@njit
def rk4_sweep(At_nodes, S_nodes, At_mid, S_mid, steps, Q, P_terminal, limit, P):
    """Fill ``P`` (N, n, n) backward (``At_*``: the transposed A matrices, C-contiguous) from ``P[N-1] = P_terminal`` by classical RK4.

    Returns ``(node, failure, peak)``: ``failure`` 0 when the sweep completed (node -1),
    1 if P became non-finite at ``node``, 2 if ``max |P|`` exceeded ``limit`` there
    (``peak`` is that maximum).
    """
    N = At_nodes.shape[0]
    P[N - 1] = P_terminal
    for k in range(N - 2, -1, -1):
        hk = steps[k]
        Pk1 = P[k + 1]
        k1 = rhs_transposed(At_nodes[k + 1], S_nodes[k + 1], Q, Pk1)
        k2 = rhs_transposed(At_mid[k], S_mid[k], Q, Pk1 + (0.5 * hk) * k1)
        k3 = rhs_transposed(At_mid[k], S_mid[k], Q, Pk1 + (0.5 * hk) * k2)
        k4 = rhs_transposed(At_nodes[k], S_nodes[k], Q, Pk1 + hk * k3)
        Pk = Pk1 + (hk / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        Pk = 0.5 * (Pk + Pk.T)
        peak = np.abs(Pk).max()
        if not np.isfinite(peak):
            return k, 1, peak
        if peak > limit:
            return k, 2, peak
        P[k] = Pk
    return -1, 0, 0.0
