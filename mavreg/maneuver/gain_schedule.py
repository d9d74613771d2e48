"""The plan's gains K(s): the transverse linearization along the nominal and the Riccati sweep.

A(s) and B(s) are computed on the nominal's grid of nodes and midpoints
(:mod:`mavreg.maneuver.nominal_grid`); RK4 steps through the nodes, evaluating A and B at
the midpoints, and P at a midpoint is the cubic Hermite interpolant of its two nodes with
the exact slopes ``P' = -F(P)`` (error O(h^4), as RK4's). The terminal condition is the
algebraic Riccati solution at the end, or the periodic solution over the last lap when the
maneuver ends going round.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..config.controller import ControllerParams
from ..config.maneuver import ManeuverSpec
from ..control.design.actuator import augmented_jacobians
from ..control.design.riccati import SweepDivergence, care, periodic_riccati, riccati_rhs, sweep_backward
from ..control.design.transverse import transverse_jacobians
from ..errors import ManeuverError
from .nominal_grid import Nominal, nominal_on_grid, with_midpoints

__all__ = ["design_gains", "linearization", "gains_on_grid", "weights", "du_ds", "first_of_runs"]

BLOCK_NODES = 512
"""Nodes per block of the midpoint and gain products (their temporaries stay small)."""


def du_ds(u: np.ndarray, s: np.ndarray, periodic: bool) -> np.ndarray:
    """du/ds on the grid s (second order, non-uniform)."""
    du = np.gradient(u, s, axis=0, edge_order=2)
    if periodic:      # the first and last points are the same point of the lap
        du[0] = du[-1] = (u[1] - u[-2]) / (s[1] - s[0] + s[-1] - s[-2])
    return du


def first_of_runs(rows: np.ndarray, rtol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the rows that differ from the row before (beyond ``rtol`` of each column's
    scale), and for every row the index of its run's first row among them."""
    scale = np.maximum(np.abs(rows).max(axis=0), 1.0)
    new = np.ones(len(rows), dtype=bool)
    new[1:] = (np.abs(np.diff(rows, axis=0)) > rtol * scale).any(axis=1)
    return np.flatnonzero(new), np.cumsum(new) - 1


def linearization(model, tau: float, nominal: Nominal, s, periodic: bool = False,
                  so3: bool = False):
    """(A, B) on the grid ``s`` of ``nominal`` (:func:`~.nominal_grid.nominal_on_grid`),
    augmented with the rotor lag when ``tau`` > 0; the attitude error on SO(3) with ``so3``,
    else the paper's roll-pitch-yaw differences.

    A and B depend on the nominal through everything but its position; where that is the
    same from one grid point to the next (a straight line flown at constant speed and
    heading: a maneuver's run-up and its slow ends), they are computed once for the run.
    """
    F, k, x, u, dx, v, R = nominal
    du = du_ds(u, s, periodic)
    rows = np.concatenate([F.reshape(len(s), -1), R.reshape(len(s), -1), k, x[:, 3:], u, dx[:, 3:],
                           v[:, None], du], axis=1)
    first, run = first_of_runs(rows)
    pick = (F[first], k[first], x[first], u[first], dx[first])
    Rbar = R[first] if so3 else None
    if tau <= 0:
        A, B = transverse_jacobians(model, *pick, Rbar=Rbar)
    else:
        A, B = augmented_jacobians(model, tau, *pick, du[first], v[first], Rbar=Rbar)
    return A[run], B[run]


def gains_on_grid(A, B, s, Q, R, P_T=None, periodic: bool = False):
    """K (and P) on the grid ``s`` of nodes and midpoints (:func:`~.nominal_grid.with_midpoints`)
    from A(s), B(s) there: RK4 through the nodes, cubic Hermite at the midpoints. ``P_T``: P at
    the last node (None: the periodic solution, the grid being one period)."""
    An, Bn, Am, Bm = A[0::2], B[0::2], A[1::2], B[1::2]
    h = np.diff(s[0::2])
    try:
        if periodic:
            Pn, _ = periodic_riccati(An, Bn, Am, Bm, h, Q, R, step_check="warn")
        else:
            Pn, _ = sweep_backward(An, Bn, Am, Bm, h, Q, R, P_T, step_check="warn")
    except SweepDivergence as exc:
        exc.s_m = float(s[0::2][exc.node])      # where, for the diagnosis
        raise
    Rinv_Bt = np.linalg.solve(R, np.swapaxes(B, 1, 2))
    P = np.empty((len(s),) + Pn.shape[1:])
    P[0::2] = Pn
    K = np.empty(Rinv_Bt.shape[:2] + Pn.shape[2:])
    # In blocks of nodes, so that the products' temporaries stay small (each row's numbers
    # are those of the whole-array expressions).
    for a in range(0, len(Pn) - 1, BLOCK_NODES):
        b = min(a + BLOCK_NODES, len(Pn) - 1)
        dP = -riccati_rhs(An[a:b + 1], Bn[a:b + 1] @ Rinv_Bt[2 * a:2 * b + 1:2], Q, Pn[a:b + 1])
        P[2 * a + 1:2 * b:2] = ((Pn[a:b] + Pn[a + 1:b + 1]) / 2
                                + h[a:b, None, None] / 8 * (dP[:-1] - dP[1:]))
    for a in range(0, len(s), 2 * BLOCK_NODES):
        np.matmul(Rinv_Bt[a:a + 2 * BLOCK_NODES], P[a:a + 2 * BLOCK_NODES], out=K[a:a + 2 * BLOCK_NODES])
    return P, K


def weights(controller: ControllerParams, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """(Q, R) of the design: the controller's, with the wrench weights when the lag is in it."""
    q = controller.q if tau <= 0 else np.concatenate([controller.q, controller.q_wrench])
    return np.diag(q), np.diag(controller.r)


def design_gains(model, path, speed, yaw, s, controller: ControllerParams, spec: ManeuverSpec, tau: float,
                 nominal: Nominal, lap: Callable[[str], None] = lambda stage: None):
    """(K on the grid ``s``, a description of the terminal condition).

    ``lap(stage)`` is called when the ``linearization`` and the ``riccati`` sweep are done
    (the caller times the stages, if it wants to: nothing here reads a clock).

    Raises
    ------
    SweepDivergence
        Where the sweep blew up (``s_m`` set: the caller explains it).
    ManeuverError
        When no terminal condition or schedule exists.
    """
    Q, R = weights(controller, tau)
    A, B = linearization(model, tau, nominal, s, so3=controller.attitude_error == "so3")
    lap("linearization")
    last = spec.segments[-1]
    try:
        if spec.laps is not None and spec.laps.segment == last.name:
            # The maneuver ends going round: the terminal condition is the periodic solution.
            terminal = "periodic (the last lap repeats)"
            P_T = _periodic_terminal(model, path, speed, yaw, spec.yaw.mode, _lap_length(last),
                                     controller, Q, R, tau)
        else:
            terminal = "steady (CARE at the end)"
            P_T, _ = care(A[-1], B[-1], Q, R)
        _, K = gains_on_grid(A, B, s, Q, R, P_T)
    except SweepDivergence:
        raise
    except ValueError as exc:
        raise ManeuverError(f"gain schedule: {exc}") from None
    lap("riccati")
    return K, terminal


def _lap_length(seg) -> float:
    """Arc length of one full turn of an arc or a helix segment."""
    shp = seg.shape
    if seg.arc is not None:
        return 2 * np.pi * shp.radius_m
    return 2 * np.pi * float(np.hypot(shp.radius_m, shp.pitch_m / (2 * np.pi)))


def _periodic_terminal(model, path, speed, yaw, yaw_mode, lap_m, controller, Q, R, tau):
    """P at the end of a path whose last lap repeats: the periodic solution over that lap.

    The lap gets a grid of its own, whose first and last nodes are one lap apart, so that
    A(s) and B(s) are periodic on it (the speed and yaw must be constant over the lap,
    else ``periodic_riccati`` says the grid is not periodic).
    """
    s1 = path.length_m
    s0 = s1 - lap_m
    v = float(speed.evaluate([s1])[0][0])
    n = max(16, int(np.ceil(lap_m / (v * controller.riccati_step_s)))) + 1
    grid = with_midpoints(np.linspace(s0, s1, n))
    A, B = linearization(model, tau, nominal_on_grid(model, path, speed, yaw, grid, yaw_mode), grid,
                         periodic=True, so3=controller.attitude_error == "so3")
    P, _ = gains_on_grid(A, B, grid, Q, R, periodic=True)
    return P[-1]
