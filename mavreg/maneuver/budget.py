"""What planning a maneuver will cost, known before anything is allocated.

Planning builds the path on nodes :data:`~mavreg.geometry.build.SPACING_M` apart and the
nominal, the linearization and the Riccati sweep on a grid of nodes ``riccati_step_s`` of
nominal time apart, with the midpoints between them. Both counts follow from the maneuver
file alone: the path's length from the segments' parameters (laps included), the flight's
duration from the speed profile along them. :func:`estimate` turns them into bytes and
seconds with per-node costs measured on the bundled maneuvers (docs/maneuvers.md, "Limits");
:func:`check_budget` refuses a maneuver over :data:`MAX_PLAN_BYTES` and says why: too many
laps, too fine a step, or too long (in metres or, at its speeds, in seconds).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..config.controller import ControllerParams
from ..config.maneuver import ManeuverSpec
from ..errors import UsageError
from ..geometry.build import SPACING_M
from .layout import profiles_at, raw_segment_bounds
from .profiles import Profile, smooth_step

__all__ = ["PlanEstimate", "PlanBudgetError", "estimate", "check_budget", "MAX_PLAN_BYTES",
           "PATH_NODE_BYTES", "GRID_NODE_BYTES"]

MAX_PLAN_BYTES = 768 * 2 ** 20
"""768 MiB of planning memory: three times the most a bundled maneuver takes (the split-S,
35 400 grid nodes, 257 MiB by this estimate), room for the barrel roll at a quarter of the
default step (the planner's own accuracy check, 593 MiB); some 110 000 grid nodes, about
10 s of planning on one core."""

PATH_NODE_BYTES = 2_500
"""Peak bytes per path node (measured: 2.46 kB for 200 m and 1 km lines)."""
GRID_NODE_BYTES = 7_000
"""Peak bytes per plan-grid node, nominal to gains (measured: 6.4-6.8 kB, barrel roll,
split-S, 6 laps, with and without the rotor lag in the design)."""
PATH_NODE_S = 45e-6
GRID_NODE_S = 80e-6
"""Seconds per path node and per grid node on one core (measured as above)."""

_DEFAULT_STEP_S = next(f.default for f in dataclasses.fields(ControllerParams)
                       if f.name == "riccati_step_s")


class PlanBudgetError(UsageError):
    """A maneuver whose plan would exceed :data:`MAX_PLAN_BYTES`; the message names the cause.

    Bad input (exit 2), like a file over the size limit: the file asks for more than planning
    may take, whatever the vehicle could fly."""


@dataclass(frozen=True)
class PlanEstimate:
    """What planning would take: the path's length and the flight's nominal duration, the
    node counts, and the bytes and seconds they cost."""

    length_m: float
    duration_s: float
    path_nodes: float
    grid_nodes: float

    @property
    def bytes(self) -> float:
        return self.path_nodes * PATH_NODE_BYTES + self.grid_nodes * GRID_NODE_BYTES

    @property
    def seconds(self) -> float:
        return self.path_nodes * PATH_NODE_S + self.grid_nodes * GRID_NODE_S

    @property
    def fits(self) -> bool:
        return self.bytes <= MAX_PLAN_BYTES


def _duration_s(speed: Profile, length_m: float) -> float:
    """Nominal flight time over [0, length_m]: exact where the speed is constant, the
    trapezoidal rule on 129 points across each change."""
    t, s, v = 0.0, 0.0, speed.initial          # speeds are > 0 (the schema)
    for s0, ln, to in speed.steps:
        a, b = min(max(s0, s), length_m), min(max(s0 + ln, s), length_m)
        t += (a - s) / v
        if b > a:
            x = np.linspace((a - s0) / ln, (b - s0) / ln, 129)
            with np.errstate(all="ignore"):
                inv_v = 1.0 / (v + (to - v) * smooth_step(x)[0])
            t += (b - a) * float(np.mean((inv_v[:-1] + inv_v[1:]) / 2))
        s, v = b, to
    return t + (length_m - s) / v


def estimate(spec: ManeuverSpec, step_s: float) -> PlanEstimate:
    """The cost of planning ``spec`` with ``riccati_step_s`` = ``step_s`` (nothing is built).

    Raises
    ------
    UsageError
        A speed or yaw change beyond its segment, or overlapping changes.
    """
    starts, ends = raw_segment_bounds(spec)
    length = max(ends.values())
    speed, _ = profiles_at(spec, starts, ends)
    duration = _duration_s(speed, length)
    return PlanEstimate(length, duration, length / SPACING_M + 1, 2 * duration / step_s + 1)


def _figures(est: PlanEstimate) -> str:
    return (f"{est.grid_nodes:.3g} grid and {est.path_nodes:.3g} path nodes, about "
            f"{est.bytes / 2 ** 20:.4g} MiB and {est.seconds:.3g} s to plan, over the budget of "
            f"{MAX_PLAN_BYTES // 2 ** 20} MiB")


def _cause(spec: ManeuverSpec, step_s: float, est: PlanEstimate) -> str:
    laps = spec.laps.count if spec.laps is not None else 1
    if laps > 1:
        one = estimate(spec.with_laps(1), step_s)
        if one.fits:
            per_lap = (est.bytes - one.bytes) / (laps - 1)
            most = 1 + int((MAX_PLAN_BYTES - one.bytes) // per_lap)
            return (f"too many laps: {laps} laps of {spec.laps.segment!r} ({est.length_m:.0f} m, "
                    f"{est.duration_s:.0f} s of flight) need {_figures(est)}; at most {most} fit")
    if step_s < _DEFAULT_STEP_S:
        coarse = estimate(spec, _DEFAULT_STEP_S)
        if coarse.fits:
            room = (MAX_PLAN_BYTES - coarse.path_nodes * PATH_NODE_BYTES) / GRID_NODE_BYTES
            finest = 2 * coarse.duration_s / max(room - 1, 1.0)
            return (f"too fine a step: riccati_step_s {step_s:g} s over {est.duration_s:.0f} s of "
                    f"flight needs {_figures(est)}; the finest that fits is about {finest:.2g} s")
    return (f"too long: {est.length_m:.4g} m taking {est.duration_s:.4g} s at its speeds needs "
            f"{_figures(est)}")


def check_budget(spec: ManeuverSpec, step_s: float) -> PlanEstimate:
    """The estimate of planning ``spec``, if within :data:`MAX_PLAN_BYTES`.

    Raises
    ------
    PlanBudgetError
        Over the budget; the message says why (laps, step or length) and by how much.
    PlanBudgetError
        A speed or yaw change beyond its segment, or overlapping changes.
    """
    est = estimate(spec, step_s)
    if not est.fits:
        raise PlanBudgetError(f"maneuver {spec.name!r} is too costly to plan: "
                              + _cause(spec, step_s, est))
    return est
