r"""Margins of the loops a flight flies: the maneuver regulator along a plan, and the hover LQR.

Both on the **lag-augmented design model**, the loop broken at the rotor commands (a common
gain or delay on the four rotors is one on the wrench; :mod:`mavreg.control.design.margins` has the
math and the methods; docs/robustness.md, *Margins*, the choices and the figures).

- **Maneuver.** At plan row i the transverse dynamics are in s (:math:`z' = A_z z + B_z\nu`,
  :mod:`mavreg.control.design.actuator`); frozen at the nominal speed, :math:`dt = ds/v`, so in time
  :math:`\dot z = v A_z z + v B_z \nu`. With lag-aware gains (15 columns) the regulator feeds
  back its own lag model of its commands, not a measured wrench
  (:func:`~mavreg.control.design.margins.lag_model_loop`); the paper's gains (11 columns) act on w
  alone, and the plant still lags by the vehicle's ``rotor_time_constant_s``.
- **Hover.** The hover LQR is designed without the lag
  (:meth:`~mavreg.control.controllers.hover.HoverController.design_loop`); the plant is that model through
  the lag (:func:`~mavreg.model.rotor_lag.lag_augment`).

Frozen-time: each row's loop is analysed as if the maneuver stood still there. That is exact
for a hover and a steady line, and an approximation where the gains and the nominal change on
the time scale of the loop; where a row's frozen loop is not even Hurwitz (the barrel roll's
exit, where the thrust drops below the weight while the vehicle slows) it is reported, not
counted. Rows: every ``stride``-th of the plan (at most ``MAX_NODES``), then every row of a
finer stride around each worst node.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..blas import one_blas_thread
from ..config.vehicle import VehicleParams
from ..errors import ManeuverError
from ..control.design.actuator import augmented_jacobians
from ..model.rotor_lag import lag_augment
from ..control.controllers.hover import HoverController, HoverParams
from ..control.design.margins import (FastLoopError, LoopMargins, ScheduleMargins, lag_model_loop, loop_margins,
                               node_margins, rotor_loop, schedule_margins)
from ..control.design.transverse import transverse_jacobians
from ..control.estimation.lag_in_effect import plant_lag_s
from ..model.mixer import mixer_matrix
from ..model.quadrotor import QuadrotorModel
from .gain_schedule import du_ds
from .plan import Plan

__all__ = ["MAX_NODES", "PlanMargins", "maneuver_loops", "maneuver_margins", "hover_margins",
           "plan_margins", "with_margins"]

MAX_NODES = 120
"""Most plan rows in the first pass (the refinement adds up to ``3 * 2 * REFINE`` more)."""
REFINE = 12
SLOW_RAD_S = 2.0
"""Frozen-time analysis does not judge the maneuver's modes slower than this: they are as slow
as the nominal changes (the barrel roll's exit slows from 7 to 3 m/s in a second; its
along-track speed error then grows at -dv/ds = 1.3 /s frozen, and decays once the vehicle
is slow again). The hover is judged whole (it is time-invariant)."""


@dataclass(frozen=True)
class PlanMargins:
    """The margins of a plan's regulator and of the hover LQR before and after it."""

    maneuver: ScheduleMargins | None
    """None for an infeasible plan (no gains)."""
    hover: LoopMargins
    hover_rotor: LoopMargins
    """The worst single-rotor loop of the hover (one rotor's gain or delay, three nominal)."""
    rotor_time_constant_s: float
    """The plant's lag the margins were computed with."""

    @property
    def delay_margin_s(self) -> float:
        """The least of the maneuver's and the hover's delay margins."""
        m = self.maneuver.delay_margin_s if self.maneuver is not None else math.inf
        return float(np.nanmin([m, self.hover.delay_margin_s]))

    def as_dict(self) -> dict:
        return {"rotor_time_constant_s": self.rotor_time_constant_s,
                "maneuver": None if self.maneuver is None else self.maneuver.as_dict(),
                "hover": self.hover.as_dict(), "hover_single_rotor": self.hover_rotor.as_dict()}


def maneuver_loops(plan: Plan, rows) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, K) in time of the regulator's frozen loops at plan rows ``rows`` (see the module)."""
    rows = np.asarray(rows, dtype=int)
    vehicle = plan.vehicle
    model = QuadrotorModel.from_vehicle(vehicle)
    tau = plant_lag_s(plan)
    _, F, k, _, _ = plan.path.evaluate(plan.s[rows])
    Rbar = plan.R[rows] if plan.attitude_error == "so3" else None
    x, u, dx, v = plan.x[rows], plan.u[rows], plan.dx[rows], plan.speed_m_s[rows]
    if tau > 0:
        du = du_ds(plan.u, plan.s, False)[rows]
        Az, Bz = augmented_jacobians(model, tau, F, k, x, u, dx, du, v, Rbar=Rbar)
    else:
        Az, Bz = transverse_jacobians(model, F, k, x, u, dx, Rbar=Rbar)
    A, B = Az * v[:, None, None], Bz * v[:, None, None]
    K = plan.K[rows]
    if K.shape[-1] == A.shape[-1] and plan.rotor_time_constant_s > 0:
        return lag_model_loop(A, B, K)
    pad = np.zeros((len(rows), 4, A.shape[-1] - K.shape[-1]))
    return A, B, np.concatenate([K, pad], axis=2)


def _rows_margins(plan: Plan, rows) -> tuple[np.ndarray, ...]:
    return node_margins(*maneuver_loops(plan, rows), slow_rad_s=SLOW_RAD_S)


def maneuver_margins(plan: Plan, max_nodes: int = MAX_NODES) -> ScheduleMargins:
    """The worst frozen-time margins along ``plan`` (every ``stride``-th row, refined around
    the worst delay margin and the worst gain margins)."""
    n = len(plan.s)
    stride = max(1, math.ceil(n / max_nodes))
    rows = np.unique(np.append(np.arange(0, n, stride), n - 1))
    tau, lo, hi = _rows_margins(plan, rows)
    worst = set()
    for values, pick in ((tau, np.nanargmin), (lo, np.nanargmax), (hi, np.nanargmin)):
        if np.any(np.isfinite(values)):
            worst.add(int(pick(np.where(np.isnan(values), np.nan, values))))
    fine = max(1, stride // REFINE)
    extra = np.setdiff1d(np.concatenate(
        [np.arange(rows[max(j - 1, 0)], rows[min(j + 1, len(rows) - 1)] + 1, fine) for j in worst]
        or [np.zeros(0, dtype=int)]), rows)
    if len(extra):
        t2, l2, h2 = _rows_margins(plan, extra)
        rows = np.concatenate([rows, extra])
        tau, lo, hi = (np.concatenate(p) for p in ((tau, t2), (lo, l2), (hi, h2)))
        order = np.argsort(rows)
        rows, tau, lo, hi = rows[order], tau[order], lo[order], hi[order]
    return schedule_margins(plan.s[rows], tau, lo, hi)


def hover_margins(vehicle: VehicleParams, params: HoverParams = HoverParams(),
                  yaw_rad: float = 0.0) -> tuple[LoopMargins, LoopMargins]:
    """(common, worst single rotor) margins of the hover LQR on the lagged design model."""
    A, B, K = HoverController(vehicle, params, compiled=False).design_loop(yaw_rad)
    tau = vehicle.rotor_time_constant_s
    if tau > 0:
        A, B = lag_augment(A, B, tau)
        K = np.hstack([K, np.zeros((4, 4))])
    common = loop_margins(A, B, K)
    M = mixer_matrix(vehicle.arm_length_m, vehicle.drag_torque_ratio_m)
    rotors = [loop_margins(*rotor_loop(A, B, K, M, i)) for i in range(4)]
    worst = LoopMargins(min(r.delay_margin_s for r in rotors), math.nan,
                        max(r.gain_margin_low for r in rotors), min(r.gain_margin_high for r in rotors),
                        all(r.stable for r in rotors))
    return common, worst


def plan_margins(plan: Plan, hover: HoverParams = HoverParams()) -> PlanMargins:
    """The margins of ``plan``'s regulator and of the hover LQR (``hover``'s weights) at the
    plan's entry yaw."""
    with one_blas_thread():
        try:
            h, h_rotor = hover_margins(plan.vehicle, hover, float(plan.x[0, 5]))
        except FastLoopError as exc:
            raise _too_fast("the hover LQR", "hover_q, hover_r_input", exc) from None
        feasible = plan.feasibility.feasible
        try:
            maneuver = maneuver_margins(plan) if feasible else None
        except FastLoopError as exc:
            raise _too_fast("the maneuver regulator", "q_*, r_input", exc) from None
        return PlanMargins(maneuver, h, h_rotor, plant_lag_s(plan))


def _too_fast(loop: str, weights: str, exc: FastLoopError) -> ManeuverError:
    """The one-line refusal of weights that no control rate can fly on this vehicle."""
    return ManeuverError(f"{loop} cannot be flown on this vehicle: {exc}, a delay margin under "
                         f"0.6 ms (shorter than any control period); weigh the torques more or the "
                         f"states less ({weights} of the controller file), or check the vehicle "
                         f"file's mass, inertia and arm")


def with_margins(plan: Plan, hover: HoverParams = HoverParams()) -> Plan:
    """``plan`` carrying its :class:`PlanMargins` (``Plan.margins``)."""
    return dataclasses.replace(plan, margins=plan_margins(plan, hover))
