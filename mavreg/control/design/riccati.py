r"""The s-varying LQR Riccati machinery of the transverse linearization (paper section 3).

The transverse linearization ``w' = A(s) w + B(s) u_w`` (``w`` in R^n, n = 11, ``u_w`` in
R^m, m = 4, ``'`` = d/ds with the arc length s as independent variable) with the cost

.. math::
    J = \int \left( w^T Q w + u_w^T R u_w \right) ds

is minimised by ``u_w = -K(s) w`` with ``K = R^{-1} B^T P`` and P the solution of the
Riccati differential equation in s,

.. math::
    -P'(s) = A^T P + P A - P S P + Q, \qquad S = B R^{-1} B^T,

integrated *backward* from a terminal condition. Three entry points:

* :func:`care` -- the constant-coefficient (algebraic) solution, a thin wrapper over
  ``scipy.linalg.solve_continuous_are``; the steady terminal condition of an open maneuver.
* :func:`sweep_backward` -- classical RK4 backward over a uniform s grid.
* :func:`periodic_riccati` -- the periodic solution ``P(s) = P(s + L)`` of a maneuver that
  repeats (laps), by repeated backward sweeps over one period.

Step size: the RK4 sweep's stability limit and the check of a grid against it live in
:mod:`mavreg.control.design.riccati_step` (re-exported here).

All functions are pure numpy/scipy: numbers in, numbers out.
"""
from __future__ import annotations


import numpy as np
import scipy.linalg

from ...accel import ACCELERATED
from .riccati_kernel import rk4_sweep_loops
from .riccati_step import RK4_STABILITY_RADIUS, check_step, max_stable_step

__all__ = [
    "RK4_STABILITY_RADIUS",
    "SweepDivergence",
    "care",
    "riccati_rhs",
    "max_stable_step",
    "check_step",
    "sweep_backward",
    "periodic_riccati",
    "rk4_sweep",
    "rk4_sweep_numpy",
]

_BLOWUP_FACTOR = 1e12


class SweepDivergence(ValueError):
    """The backward sweep became non-finite or blew up at grid node ``node``, ``offset_m``
    of s after the first node."""

    def __init__(self, message: str, node: int, offset_m: float):
        super().__init__(message)
        self.node = node
        self.offset_m = offset_m


def _validate_weights(Q, R, n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    Q = np.asarray(Q, dtype=float)
    R = np.asarray(R, dtype=float)
    if Q.shape != (n, n):
        raise ValueError(f"Q has shape {Q.shape}, expected ({n}, {n})")
    if R.shape != (m, m):
        raise ValueError(f"R has shape {R.shape}, expected ({m}, {m})")
    if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(R))):
        raise ValueError("Q and R must be finite")
    if not np.allclose(Q, Q.T, rtol=1e-12, atol=1e-14 * max(1.0, np.abs(Q).max())):
        raise ValueError("Q must be symmetric")
    if np.linalg.eigvalsh(0.5 * (Q + Q.T)).min() < -1e-12 * max(1.0, np.abs(Q).max()):
        raise ValueError("Q must be positive semidefinite")
    try:
        np.linalg.cholesky(0.5 * (R + R.T))
    except np.linalg.LinAlgError:
        raise ValueError("R must be symmetric positive definite") from None
    return 0.5 * (Q + Q.T), 0.5 * (R + R.T)


def _uncontrollable_unstable_modes(A: np.ndarray, B: np.ndarray) -> list[complex]:
    """Eigenvalues with Re >= 0 failing the PBH rank test rank[A - lambda I, B] = n."""
    n = A.shape[0]
    scale = max(1.0, np.abs(A).max(), np.abs(B).max())
    bad = []
    for lam in np.linalg.eigvals(A):
        if lam.real < -1e-9 * scale:
            continue
        sv = np.linalg.svd(np.hstack([A - lam * np.eye(n), B]), compute_uv=False)
        if sv[-1] <= 1e-9 * scale:
            bad.append(complex(lam))
    return bad


def care(A, B, Q, R) -> tuple[np.ndarray, np.ndarray]:
    r"""Stabilizing solution of the continuous algebraic Riccati equation.

    .. math::
        A^T P + P A - P B R^{-1} B^T P + Q = 0, \qquad K = R^{-1} B^T P,

    computed by ``scipy.linalg.solve_continuous_are``. ``A - B K`` is Hurwitz.

    Parameters
    ----------
    A : (n, n) array_like
    B : (n, m) array_like
    Q : (n, n) array_like, symmetric positive semidefinite
    R : (m, m) array_like, symmetric positive definite

    Returns
    -------
    P : (n, n) ndarray, symmetric
    K : (m, n) ndarray

    Raises
    ------
    ValueError
        If (A, B) is not stabilizable (an eigenvalue with Re >= 0 fails the PBH test), if
        scipy fails, or if the result is not finite / not stabilizing (e.g. (Q, A) has an
        unobservable mode on the imaginary axis).
    """
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n = A.shape[0]
    if A.shape != (n, n) or B.ndim != 2 or B.shape[0] != n:
        raise ValueError(f"A {A.shape} and B {B.shape} do not form an (n,n), (n,m) pair")
    Q, R = _validate_weights(Q, R, n, B.shape[1])
    bad = _uncontrollable_unstable_modes(A, B)
    if bad:
        modes = ", ".join(f"{z.real:.6g}{z.imag:+.6g}j" for z in bad)
        raise ValueError(f"(A, B) is not stabilizable: uncontrollable modes with Re >= 0: {modes}")
    try:
        P = scipy.linalg.solve_continuous_are(A, B, Q, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise ValueError(f"the algebraic Riccati equation has no stabilizing solution: {exc}") from exc
    if not np.all(np.isfinite(P)):
        raise ValueError("the algebraic Riccati equation returned a non-finite solution")
    P = 0.5 * (P + P.T)
    K = np.linalg.solve(R, B.T @ P)
    lam = np.linalg.eigvals(A - B @ K)
    if lam.real.max() >= 0.0:
        raise ValueError(
            f"the Riccati solution is not stabilizing (closed-loop eigenvalue with real part "
            f"{lam.real.max():.3g}); check that (Q, A) has no unobservable imaginary-axis mode"
        )
    return P, K


def riccati_rhs(A: np.ndarray, S: np.ndarray, Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    r"""``F(P) = A^T P + P A - P S P + Q`` with ``S = B R^{-1} B^T``, so that ``-P' = F``.
    Stacks ``(N, n, n)`` give a stack."""
    AtP = np.swapaxes(A, -1, -2) @ P
    return AtP + np.swapaxes(AtP, -1, -2) - P @ S @ P + Q


def _rhs_transposed(At, S, Q, P):
    r"""``F(P) = A^T P + P A - P S P + Q``, so that ``-P' = F``; ``At`` is ``A^T``, P
    symmetric (so that ``P A = (A^T P)^T``)."""
    AtP = At @ P
    return AtP + AtP.T - P @ (S @ P) + Q


def rk4_sweep_numpy(At_nodes, S_nodes, At_mid, S_mid, steps, Q, P_terminal, limit, P):
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
        k1 = _rhs_transposed(At_nodes[k + 1], S_nodes[k + 1], Q, Pk1)
        k2 = _rhs_transposed(At_mid[k], S_mid[k], Q, Pk1 + (0.5 * hk) * k1)
        k3 = _rhs_transposed(At_mid[k], S_mid[k], Q, Pk1 + (0.5 * hk) * k2)
        k4 = _rhs_transposed(At_nodes[k], S_nodes[k], Q, Pk1 + hk * k3)
        Pk = Pk1 + (hk / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
        Pk = 0.5 * (Pk + Pk.T)
        peak = np.abs(Pk).max()
        if not np.isfinite(peak):
            return k, 1, peak
        if peak > limit:
            return k, 2, peak
        P[k] = Pk
    return -1, 0, 0.0


rk4_sweep = rk4_sweep_loops if ACCELERATED else rk4_sweep_numpy
"""The sweep of the path in use: the loops compiled (:mod:`.riccati_kernel`), numpy in plain
Python (in plain Python the loops would be two orders slower)."""


def _validate_grid(A_nodes, B_nodes, A_mid, B_mid, h):
    A_nodes = np.asarray(A_nodes, dtype=float)
    B_nodes = np.asarray(B_nodes, dtype=float)
    A_mid = np.asarray(A_mid, dtype=float)
    B_mid = np.asarray(B_mid, dtype=float)
    if A_nodes.ndim != 3 or A_nodes.shape[1] != A_nodes.shape[2]:
        raise ValueError(f"A_nodes must have shape (N, n, n), not {A_nodes.shape}")
    N, n, _ = A_nodes.shape
    if N < 2:
        raise ValueError("the grid needs at least 2 nodes")
    if B_nodes.ndim != 3 or B_nodes.shape[:2] != (N, n):
        raise ValueError(f"B_nodes must have shape ({N}, {n}, m), not {B_nodes.shape}")
    m = B_nodes.shape[2]
    if A_mid.shape != (N - 1, n, n) or B_mid.shape != (N - 1, n, m):
        raise ValueError(f"A_mid {A_mid.shape} / B_mid {B_mid.shape} must be "
                         f"({N - 1}, {n}, {n}) / ({N - 1}, {n}, {m})")
    for name, arr in (("A_nodes", A_nodes), ("B_nodes", B_nodes), ("A_mid", A_mid),
                      ("B_mid", B_mid)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} is not finite")
    h_arr = np.asarray(h, dtype=float)
    if h_arr.ndim > 1 or (h_arr.ndim == 1 and h_arr.shape != (N - 1,)):
        raise ValueError(f"h must be a scalar or have shape ({N - 1},), not {h_arr.shape}")
    if not (np.all(np.isfinite(h_arr)) and np.all(h_arr > 0.0)):
        raise ValueError(f"step h must be positive and finite, not {h}")
    return A_nodes, B_nodes, A_mid, B_mid, N, n, m


def _transposed(A: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(A.transpose(0, 2, 1))


def sweep_backward(A_nodes, B_nodes, A_mid, B_mid, h: float, Q, R, P_terminal, *,
                   step_check: str = "raise", safety: float = 0.5
                   ) -> tuple[np.ndarray, np.ndarray]:
    r"""Integrate the Riccati differential equation backward in s with classical RK4.

    Grid ``s_k = s_0 + k h``, ``k = 0..N-1``; ``P(s_{N-1}) = P_terminal``. With
    ``F(s, P) = A^T P + P A - P S P + Q`` and ``P' = -F``, one step from ``s_{k+1}`` to
    ``s_k`` is

    .. math::
        k_1 = F(s_{k+1}, P_{k+1}),\;
        k_2 = F(s_{k+\frac12}, P_{k+1} + \tfrac h2 k_1),\;
        k_3 = F(s_{k+\frac12}, P_{k+1} + \tfrac h2 k_2),\;
        k_4 = F(s_k, P_{k+1} + h k_3),\\
        P_k = P_{k+1} + \tfrac h6 (k_1 + 2 k_2 + 2 k_3 + k_4),

    the two middle stages using the midpoint matrices ``A_mid[k]``, ``B_mid[k]``. P is
    symmetrized after each step. Global error O(h^4).

    Parameters
    ----------
    A_nodes : (N, n, n) array_like, A(s_k)
    B_nodes : (N, n, m) array_like, B(s_k)
    A_mid : (N-1, n, n) array_like, A(s_k + h/2)
    B_mid : (N-1, n, m) array_like, B(s_k + h/2)
    h : float or (N-1,) array, grid spacing (> 0, in the unit of s); an array gives a
        non-uniform grid, interval k being [s_k, s_k + h_k]
    Q : (n, n) symmetric PSD;  R : (m, m) symmetric PD
    P_terminal : (n, n) symmetric PSD, P at the last node (e.g. :func:`care` there)
    step_check : {"raise", "warn", "off"}
        After the sweep, check ``h`` against the RK4 stability limit at every node with the
        gains found (see :func:`check_step`).
    safety : float
        Fraction of the stability limit above which a warning is issued.

    Returns
    -------
    P : (N, n, n) ndarray, P(s_k)
    K : (N, m, n) ndarray, K(s_k) = R^{-1} B(s_k)^T P(s_k)

    Raises
    ------
    ValueError
        On bad shapes or weights, if P becomes non-finite or blows up (norm beyond 1e12 times
        the scale of Q and P_terminal; the message gives the node index and s - s_0), or if
        the step violates the RK4 stability limit and ``step_check="raise"``.
    """
    A_nodes, B_nodes, A_mid, B_mid, N, n, m = _validate_grid(A_nodes, B_nodes, A_mid, B_mid, h)
    Q, R = _validate_weights(Q, R, n, m)
    P_T = np.asarray(P_terminal, dtype=float)
    if P_T.shape != (n, n) or not np.all(np.isfinite(P_T)):
        raise ValueError(f"P_terminal must be a finite ({n}, {n}) matrix")
    Rinv = scipy.linalg.cho_solve(scipy.linalg.cho_factor(R), np.eye(m))
    Rinv_Bt_nodes = Rinv @ B_nodes.transpose(0, 2, 1)
    S_nodes = B_nodes @ Rinv_Bt_nodes
    S_mid = B_mid @ (Rinv @ B_mid.transpose(0, 2, 1))
    limit = _BLOWUP_FACTOR * max(1.0, np.abs(Q).max(), np.abs(P_T).max())
    steps = np.ascontiguousarray(np.broadcast_to(np.asarray(h, dtype=float), (N - 1,)))
    P = np.empty((N, n, n))
    node, failure, peak = rk4_sweep(_transposed(A_nodes), S_nodes, _transposed(A_mid), S_mid, steps,
                                    Q, 0.5 * (P_T + P_T.T), limit, P)
    if failure:
        offset = float(np.sum(steps[:node]))
        if failure == 1:
            raise SweepDivergence(f"Riccati sweep became non-finite at node {node} "
                                  f"(s - s0 = {offset:.6g})", node, offset)
        raise SweepDivergence(f"Riccati sweep blew up at node {node} (s - s0 = {offset:.6g}): "
                              f"max |P| = {peak:.3g}; reduce the step h = {steps[node]:.4g}",
                              node, offset)
    K = Rinv_Bt_nodes @ P
    check_step(A_nodes, B_nodes, K, h, safety=safety, mode=step_check)
    return P, K


def periodic_riccati(A_nodes, B_nodes, A_mid, B_mid, h: float, Q, R, tol: float = 1e-10,
                     max_periods: int = 200, *, step_check: str = "raise",
                     safety: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    r"""Periodic solution ``P(s) = P(s + L)`` of the Riccati equation over one period.

    The grid covers exactly one period ``L = (N - 1) h``: node ``N-1`` is node 0 again
    (``A_nodes[0] == A_nodes[-1]``, same for B). Starting from the :func:`care` solution of
    the period-averaged system (or, if that is not stabilizable, of node 0), sweep backward
    over the period, restart the next sweep from the ``P(s_0)`` just found, and stop when

    .. math::
        \frac{\|P(s_0) - P(s_0 + L)\|_F}{\|P(s_0)\|_F} < \mathrm{tol}.

    Why it converges: the one-period backward map ``P(L) -> P(0)`` of a stabilizable,
    detectable periodic system has the periodic solution as an attracting fixed point.
    Linearised about it, ``dP(0) = Phi_c^T dP(L) Phi_c`` with ``Phi_c`` the closed-loop
    monodromy matrix (state transition of ``A - B K`` over one period), whose Floquet
    multipliers lie inside the unit circle; the residual thus contracts by about
    ``rho(Phi_c)^2`` per period. The RK4 discretisation has its own fixed point, O(h^4) from
    the exact one, to which the iteration converges to round-off.

    Parameters
    ----------
    A_nodes, B_nodes, A_mid, B_mid, h, Q, R
        As :func:`sweep_backward`, over one period.
    tol : float
        Relative periodicity residual to reach.
    max_periods : int
        Most backward sweeps to try.
    step_check, safety
        As :func:`sweep_backward` (checked on the final sweep only).

    Returns
    -------
    P : (N, n, n) ndarray with ``P[0]`` equal to ``P[-1]`` to ``tol``
    K : (N, m, n) ndarray

    Raises
    ------
    ValueError
        If the grid is not periodic, if no starting CARE solution exists, if a sweep blows
        up, or if the residual is still above ``tol`` after ``max_periods`` sweeps (the
        message gives the residual).
    """
    A_nodes, B_nodes, A_mid, B_mid, N, n, m = _validate_grid(A_nodes, B_nodes, A_mid, B_mid, h)
    for name, arr in (("A_nodes", A_nodes), ("B_nodes", B_nodes)):
        scale = max(1.0, np.abs(arr).max())
        if np.abs(arr[0] - arr[-1]).max() > 1e-9 * scale:
            raise ValueError(f"{name}[0] and {name}[-1] differ by "
                             f"{np.abs(arr[0] - arr[-1]).max():.3g}: the grid must cover "
                             "exactly one period")
    if max_periods < 1:
        raise ValueError("max_periods must be at least 1")
    # Period average by the composite trapezoid rule on the nodes.
    A_avg = A_nodes[:-1].mean(axis=0)
    B_avg = B_nodes[:-1].mean(axis=0)
    try:
        P_end, _ = care(A_avg, B_avg, Q, R)
    except ValueError:
        try:
            P_end, _ = care(A_nodes[-1], B_nodes[-1], Q, R)
        except ValueError as exc:
            raise ValueError("periodic Riccati: neither the period-averaged system nor the "
                             f"system at s0 gives a starting solution: {exc}") from exc
    residual = np.inf
    for period in range(1, max_periods + 1):
        P, K = sweep_backward(A_nodes, B_nodes, A_mid, B_mid, h, Q, R, P_end, step_check="off")
        residual = np.linalg.norm(P[0] - P_end) / max(np.linalg.norm(P[0]), np.finfo(float).tiny)
        P_end = P[0]
        if residual < tol:
            P[-1] = P[0]
            K[-1] = K[0]
            check_step(A_nodes, B_nodes, K, h, safety=safety, mode=step_check)
            return P, K
    raise ValueError(f"periodic Riccati did not converge in {max_periods} periods: relative "
                     f"residual |P(0) - P(L)| / |P(0)| = {residual:.3g} > tol = {tol:.3g}")
