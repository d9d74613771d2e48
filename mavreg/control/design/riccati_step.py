r"""The RK4 Riccati sweep's step size: its stability limit and the check of a grid against it.

Linearised about the solution, an error ``dP`` obeys (in reversed s, ``tau = -s``)
``dP_tau = A_c^T dP + dP A_c`` with the closed-loop matrix ``A_c = A - B K``: a Lyapunov
operator with eigenvalues ``mu_ij = lambda_i + lambda_j`` (``lambda`` the eigenvalues of
``A_c``, all in the open left half-plane for an LQR closed loop). RK4 is stable on the
mode ``mu`` iff ``|R(h mu)| <= 1`` with ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``; that
region crosses the negative real axis at 2.785 and contains the whole half-disc of radius
2.6 in the left half-plane. :func:`max_stable_step` therefore returns
``safety * 2.5 / max |lambda_i + lambda_j|`` (``<= 2 |lambda_max|``), and
the sweep checks the step against it at every node afterwards (:func:`check_step`).

:func:`~mavreg.control.design.riccati.sweep_backward` and
:func:`~mavreg.control.design.riccati.periodic_riccati` call :func:`check_step` after their sweep;
both names are also importable from :mod:`mavreg.control.design.riccati`. Pure numpy.
"""
from __future__ import annotations

import warnings

import numpy as np

__all__ = ["RK4_STABILITY_RADIUS", "MAX_CHECKED_NODES", "max_stable_step", "check_step"]

RK4_STABILITY_RADIUS = 2.5
"""Radius of a left half-disc inside RK4's absolute stability region (true minimum ~2.6)."""

MAX_CHECKED_NODES = 1024
"""Most nodes whose closed-loop eigenvalues :func:`check_step` computes."""


def max_stable_step(A, B, K, safety: float = 0.5) -> float:
    r"""Largest s step that keeps the RK4 Riccati sweep stable, times ``safety``.

    .. math::
        h_{max} = \mathrm{safety} \cdot \frac{2.5}{\max_{ij} |\lambda_i + \lambda_j|},
        \qquad \lambda = \mathrm{eig}(A - B K),

    ``A``, ``B``, ``K`` may be single matrices or stacks ``(N, n, n)``, ``(N, n, m)``,
    ``(N, m, n)``; the minimum over the stack is returned. ``safety = 1`` is the stability
    edge; the default 0.5 keeps ``h |lambda_max| <= 0.625`` where RK4 is also accurate.
    Returns ``inf`` for a zero closed-loop matrix. Note that the transient of a sweep
    started far from the steady solution (e.g. ``P_terminal = 0``) passes through gains
    whose closed loop can be faster than the steady one; the post-sweep
    :func:`check_step` looks at every node.
    """
    h_abs = _stable_step_per_node(A, B, K)
    return float(safety * h_abs.min())


def _stable_step_per_node(A, B, K) -> np.ndarray:
    A = np.asarray(A, dtype=float)
    Acl = A - np.asarray(B, dtype=float) @ np.asarray(K, dtype=float)
    if Acl.ndim == 2:
        Acl = Acl[None]
    lam = np.linalg.eigvals(Acl)                          # (N, n)
    mu = np.abs(lam[:, :, None] + lam[:, None, :]).max(axis=(1, 2))
    with np.errstate(divide="ignore"):
        return np.where(mu > 0.0, RK4_STABILITY_RADIUS / np.where(mu > 0.0, mu, 1.0), np.inf)


def check_step(A_nodes, B_nodes, K_nodes, h: float, safety: float = 0.5,
               mode: str = "raise") -> None:
    """Check the step ``h`` against :func:`max_stable_step` at every node, or at most
    ``MAX_CHECKED_NODES`` nodes evenly spread (the first and last among them).

    The eigenvalues of the closed loop cost more than the sweep itself; a long plan (10,000
    nodes a few milliseconds of flight apart) is checked every few nodes, which the gains do
    not outrun: they change on the time scale of the maneuver, not of one step.

    Beyond the stability edge (``safety = 1``) the sweep is meaningless: raise
    ``ValueError`` in ``mode="raise"``, warn in ``mode="warn"``. Between ``safety`` and the
    edge it is stable but inaccurate on the fastest closed-loop modes: warn
    (``RuntimeWarning``) in both modes. ``mode="off"`` does nothing.
    """
    if mode == "off":
        return
    if mode not in ("raise", "warn"):
        raise ValueError(f"mode must be 'raise', 'warn' or 'off', not {mode!r}")
    n_nodes = len(K_nodes)
    pick = np.unique(np.linspace(0, n_nodes - 1, min(n_nodes, MAX_CHECKED_NODES)).round().astype(int))
    h_edge = _stable_step_per_node(np.asarray(A_nodes)[pick], np.asarray(B_nodes)[pick],
                                   np.asarray(K_nodes)[pick])
    steps = _node_steps(h, n_nodes)[pick]
    i = int(np.argmax(steps / h_edge))
    worst = int(pick[i])
    h, edge = float(steps[i]), float(h_edge[i])
    if h > edge:
        msg = (f"RK4 Riccati step h = {h:.4g} exceeds the stability limit {edge:.4g} "
               f"at node {worst}; use a step below "
               f"{safety * edge:.4g}")
        if mode == "raise":
            raise ValueError(msg)
        warnings.warn(msg, RuntimeWarning, stacklevel=3)
    elif h > safety * edge:
        warnings.warn(
            f"RK4 Riccati step h = {h:.4g} is above {safety} of the stability limit "
            f"{edge:.4g} at node {worst}: the fastest "
            "closed-loop modes are resolved poorly", RuntimeWarning, stacklevel=3)


def _node_steps(h, n_nodes: int) -> np.ndarray:
    """Step lengths seen by each node: the larger of the intervals on either side."""
    steps = np.broadcast_to(np.asarray(h, dtype=float), (n_nodes - 1,))
    return np.maximum(np.concatenate([steps[:1], steps]), np.concatenate([steps, steps[-1:]]))
