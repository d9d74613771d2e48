"""Everything a flight needs, built off the control loop: path, nominal, feasibility, gains.

:func:`plan_spec` plans a loaded maneuver in stages: the path, its profiles and the grid
(:mod:`.nominal_grid`), the nominal by differential flatness and its feasibility
(:mod:`.feasibility`), the linearization and the Riccati sweep (:mod:`.gain_schedule`).
:func:`plan_from_entry` puts stored gains (a plan cache's
:class:`~mavreg.maneuver.plan_entry.PlanEntry`) on the path and nominal computed again, bit
for bit as planning computes them.

Pure: no file and no clock is read here. Files, uploads and the on-disk cache are
:mod:`mavreg.planning`'s (``plan_file``, ``plan_text``, ``plan_cached``); a caller that
wants the stages timed hands :func:`plan_spec` a clock.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Callable, NamedTuple

import numpy as np

from ..config.controller import ControllerParams
from ..config.maneuver import ManeuverSpec
from ..config.vehicle import VehicleParams
from ..control.controllers.attitude_table import NominalAttitudes
from ..control.design.riccati import SweepDivergence
from ..blas import one_blas_thread
from ..errors import ManeuverError
from ..geometry.build import build_path
from ..geometry.path import Path
from ..model.mixer import Mixer
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import rpy_to_matrix
from .diagnose import euler_singularity, explain_divergence
from .feasibility import Feasibility, check_feasibility
from .budget import check_budget
from .gain_schedule import design_gains
from .layout import build_profiles, segment_ends, segment_starts
from .nominal_grid import Nominal, nominal_on_grid, time_grid, with_midpoints
from .plan_entry import PlanEntry
from .profiles import Profile

__all__ = ["Plan", "plan_spec", "plan_from_entry", "segment_starts", "segment_ends", "build_profiles"]


@dataclass(frozen=True)
class Plan:
    """A planned maneuver: nominal x(s), u(s), gains K(s) on a common grid of s.

    ``dx`` is dx/ds = f(x, u)/v, used for Hermite interpolation of the nominal. ``K`` is
    (N, 4, 11) for the paper's design, or (N, 4, 15) when the rotor lag is in the design
    (``rotor_time_constant_s`` > 0): the last four columns act on the achieved wrench's
    deviation from the nominal (:mod:`mavreg.control.design.actuator`).
    """

    name: str
    path: Path
    vehicle: VehicleParams
    s: np.ndarray
    x: np.ndarray
    dx: np.ndarray
    u: np.ndarray
    K: np.ndarray
    speed_m_s: np.ndarray
    feasibility: Feasibility
    terminal: str
    laps: int
    laps_segment: str | None
    rotor_time_constant_s: float = 0.0
    """The rotor lag the gains were designed with (0: the paper's design)."""
    R: np.ndarray | None = None
    """Nominal attitude (N, 3, 3), body to NED, on the grid s: the reference of the SO(3)
    attitude error, and everywhere the roll-pitch-yaw columns of x are singular."""
    attitude_error: str = "rpy"
    """The gains' attitude error: ``rpy`` (the paper's roll-pitch-yaw differences) or
    ``so3`` (the rotation vector Log(Rbar^T R), :mod:`mavreg.model.so3`)."""
    margins: object | None = None
    """Delay and gain margins (:class:`~mavreg.maneuver.plan_margins.PlanMargins`), when computed
    (:func:`~mavreg.maneuver.plan_margins.with_margins`): not by planning itself."""
    from_cache: bool = False
    """Served by the plan cache (:mod:`mavreg.planning.cache`) rather than planned now."""

    @cached_property
    def _attitudes(self) -> NominalAttitudes:
        """The nominal attitude's table over every row (built at the first query)."""
        R = self.R if self.R is not None else np.moveaxis(rpy_to_matrix(*self.x[:, 3:6].T), -1, 0)
        return NominalAttitudes(self.s, R, self.x[:, 9:12] / self.speed_m_s[:, None])

    def _rows(self, s):
        """(row, fraction) of arc lengths ``s`` clamped to the grid."""
        s = np.clip(s, self.s[0], self.s[-1])
        i = np.clip(np.searchsorted(self.s, s) - 1, 0, len(self.s) - 2)
        return i, (s - self.s[i]) / (self.s[i + 1] - self.s[i])

    def nominal_attitude(self, s: float) -> np.ndarray:
        """Rbar(s) (3, 3) between the grid rows around s (clamped), by the cubic in the
        rotation vector of :class:`~mavreg.control.controllers.attitude_table.NominalAttitudes`."""
        i, a = self._rows(float(s))
        return self._attitudes.at(int(i), float(a))

    def nominal_attitudes(self, s) -> np.ndarray:
        """:meth:`nominal_attitude` at every arc length of ``s`` (K,): (K, 3, 3), vectorized
        (the same rotations to rounding)."""
        i, a = self._rows(np.asarray(s, dtype=float))
        return self._attitudes.at_many(i, a)

    @property
    def length_m(self) -> float:
        return self.path.length_m

    @property
    def segments(self) -> tuple[tuple[str, float, float], ...]:
        return tuple((sp.name, sp.s_start_m, sp.s_end_m) for sp in self.path.spans)

    @property
    def entry_state(self) -> np.ndarray:
        return self.x[0].copy()

    @property
    def duration_s(self) -> float:
        """Nominal flight time: the integral of ds / v(s)."""
        return float(np.sum(np.diff(self.s) * 2 / (self.speed_m_s[1:] + self.speed_m_s[:-1])))

    def nominal_state(self, s: float) -> np.ndarray:
        """x(s), cubic Hermite between grid nodes (clamped to the ends)."""
        i, u = self._rows(float(s))
        h = self.s[i + 1] - self.s[i]
        h00, h10 = 2 * u ** 3 - 3 * u ** 2 + 1, u ** 3 - 2 * u ** 2 + u
        h01, h11 = -2 * u ** 3 + 3 * u ** 2, u ** 3 - u ** 2
        return (h00 * self.x[i] + h10 * h * self.dx[i] + h01 * self.x[i + 1]
                + h11 * h * self.dx[i + 1])

    def _top_of_loop_thrust(self) -> dict:
        """Thrust where the laps segment (else the whole path) is highest: a loop's top."""
        span = next((sp for sp in self.path.spans if sp.name == self.laps_segment), None)
        sel = (self.s >= span.s_start_m) & (self.s <= span.s_end_m) if span else slice(None)
        s_sel = self.s[sel]
        z = self.path.evaluate(s_sel)[0][:, 2]
        i = int(np.argmin(z))
        return {"at_highest_point": float(self.u[sel][i, 0]), "highest_point_s_m": float(s_sel[i])}

    def summary(self) -> dict:
        """JSON-ready summary (``mavreg plan --json``)."""
        f = self.feasibility
        top = self._top_of_loop_thrust()
        return {
            "name": self.name,
            "feasible": f.feasible,
            "violations": list(f.violations),
            "length_m": self.length_m,
            "duration_s": self.duration_s,
            "laps": self.laps,
            "speed_m_s": {"min": f.speed_m_s[0], "max": f.speed_m_s[1]},
            "thrust_n": {"min": f.thrust_n[0], "max": f.thrust_n[1], **top},
            "rotor_force_n": {"min": f.rotor_force_n[0], "max": f.rotor_force_n[1],
                              "limit": self.vehicle.max_rotor_thrust_n},
            "torque_nm": {"max_abs": list(f.torque_max_abs_nm)},
            "gain_schedule": {"nodes": int(len(self.s)), "terminal": self.terminal,
                              "attitude_error": self.attitude_error,
                              "max_abs_gain": float(np.abs(self.K).max())},
            "segments": [{"name": n, "s_start_m": a, "s_end_m": b} for n, a, b in self.segments],
            "from_cache": self.from_cache,
            **({} if self.margins is None else {"margins": self.margins.as_dict()}),
        }


class _Stopwatch:
    """Seconds spent in each stage, added into ``timings`` (a dict, or None: not kept), read
    from the caller's ``clock`` (seconds, monotonic; None: nothing is timed)."""

    def __init__(self, timings: dict | None, clock: Callable[[], float] | None):
        if timings is not None and clock is None:
            raise ValueError("plan_spec: timings need a clock (e.g. time.perf_counter); "
                             "the planner reads none of its own")
        self.timings = timings
        self.clock = clock
        self._t0 = self._last = clock() if timings is not None else 0.0

    def lap(self, stage: str) -> None:
        if self.timings is not None:
            now = self.clock()
            self.timings[stage] = self.timings.get(stage, 0.0) + now - self._last
            self.timings["total"] = now - self._t0
            self._last = now


class _Stage(NamedTuple):
    """Everything of a plan but its gains: what a cache entry (:mod:`.plan_entry`) leaves out."""

    spec: ManeuverSpec
    vehicle: VehicleParams
    model: QuadrotorModel
    path: Path
    speed: Profile
    yaw: Profile
    s: np.ndarray
    nominal: Nominal
    rotors: np.ndarray
    feasibility: Feasibility

    def plan(self, K: np.ndarray, terminal: str, tau: float, attitude_error: str) -> Plan:
        spec, n = self.spec, self.nominal
        laps = spec.laps.count if spec.laps is not None else 1
        laps_seg = spec.laps.segment if spec.laps is not None else None
        return Plan(spec.name, self.path, self.vehicle, self.s, n.x, n.dx, n.u, K, n.v,
                    self.feasibility, terminal, laps, laps_seg, tau, R=n.R,
                    attitude_error=attitude_error)


def _stage(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
           clock: _Stopwatch) -> _Stage:
    """The path, the grid, the nominal and its feasibility."""
    model = QuadrotorModel.from_vehicle(vehicle)
    mixer = Mixer.from_vehicle(vehicle)
    path = build_path(spec)
    speed, yaw = build_profiles(spec, path)
    s = with_midpoints(time_grid(path, speed, controller.riccati_step_s))
    clock.lap("path")
    nominal = nominal_on_grid(model, path, speed, yaw, s, spec.yaw.mode)
    rotors = nominal.u @ mixer.inverse.T
    ri = vehicle.rate_interface if vehicle.output == "rates" else None
    feas = check_feasibility(s, nominal.u, rotors, nominal.v, vehicle.max_rotor_thrust_n,
                             spec.limits.min_speed_m_s, lambda q: path.segment_at(q).name,
                             nominal.R, spec.limits.max_tilt_rad, nominal.x[:, 9:12],
                             None if ri is None else ri.max_body_rate_rad_s)
    clock.lap("nominal")
    return _Stage(spec, vehicle, model, path, speed, yaw, s, nominal, rotors, feas)


def plan_spec(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
              strict: bool = True, *, timings: dict | None = None,
              clock: Callable[[], float] | None = None) -> Plan:
    """Plan a loaded maneuver.

    With ``strict``, an infeasible nominal raises :class:`ManeuverError` naming where and
    by how much; otherwise the plan is returned with ``feasibility.feasible`` False (and
    no gains are computed for an infeasible plan: ``K`` is zeros). ``timings``: a dict to
    receive the seconds spent on the ``path`` (with the profiles and the grid), the
    ``nominal`` (with its feasibility), the ``linearization``, the ``riccati`` sweep, and
    the ``total``, read from ``clock`` (e.g. ``time.perf_counter``; required with
    ``timings``: the planner reads no clock of its own).
    """
    watch = _Stopwatch(timings, clock)     # from here: the thread limit's set-up is counted
    check_budget(spec, controller.riccati_step_s)      # before anything is allocated
    with one_blas_thread():
        return _plan_spec(spec, vehicle, controller, strict, watch)


def _plan_spec(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
               strict: bool, clock: _Stopwatch) -> Plan:
    st = _stage(spec, vehicle, controller, clock)
    s, x, v, path, nominal = st.s, st.nominal.x, st.nominal.v, st.path, st.nominal
    if not st.feasibility.feasible:
        if strict:
            raise ManeuverError(f"maneuver {spec.name!r} is infeasible: "
                                + "; ".join(st.feasibility.violations))
        return st.plan(np.zeros((len(s), 4, 11)), "none (infeasible)", 0.0, controller.attitude_error)
    so3 = controller.attitude_error == "so3"
    singular = None if so3 else euler_singularity(s, x[:, 4], lambda q: path.segment_at(q).name)
    if singular:
        raise ManeuverError(f"maneuver {spec.name!r}: {singular}")
    tau = vehicle.rotor_time_constant_s if controller.rotor_lag_in_design else 0.0
    if controller.rotor_lag_in_design and not tau > 0:
        raise ManeuverError("the controller puts the rotor lag in the design "
                            "(rotor_lag_in_design: true) but the vehicle file's "
                            "rotor_time_constant_s is 0")
    try:
        K, terminal = design_gains(st.model, path, st.speed, st.yaw, s, controller, spec, tau, nominal,
                                   clock.lap)
    except SweepDivergence as exc:
        k = nominal.k
        pitch = np.zeros(len(s)) if so3 else x[:, 4]     # no singularity in the SO(3) form
        raise ManeuverError(f"maneuver {spec.name!r}: " + explain_divergence(
            exc.s_m, s, pitch, v, st.rotors, vehicle.max_rotor_thrust_n, np.hypot(k[:, 0], k[:, 1]),
            lambda q: path.segment_at(q).name) + f" ({exc})") from None
    return st.plan(K, terminal, tau, controller.attitude_error)


def plan_from_entry(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
                    entry: object) -> Plan | None:
    """The plan of ``spec`` with the gains a cache ``entry`` stored
    (:class:`~mavreg.maneuver.plan_entry.PlanEntry`), the path and the nominal computed again
    (bit for bit as :func:`plan_spec` computes them); ``from_cache`` set. None when the entry
    does not fit: not a ``PlanEntry``, gains for another grid, or damaged (zlib, shape): the
    caller plans again."""
    if not isinstance(entry, PlanEntry):
        return None
    st = _stage(spec, vehicle, controller, _Stopwatch(None, None))
    try:
        K = entry.gain_table() if entry.gains_shape[0] == len(st.s) else None
    except Exception:          # a damaged entry (zlib, shape): planned again, as an unreadable one
        K = None
    if K is None:
        return None
    return replace(st.plan(K, entry.terminal, entry.rotor_time_constant_s, controller.attitude_error),
                   from_cache=True)
