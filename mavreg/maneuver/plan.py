"""Everything a flight needs, built off the control loop: path, nominal, feasibility, gains.

The Riccati sweep steps through arc lengths evenly spaced in *nominal time*
(``riccati_step_s`` apart): the s-domain Riccati equation is as stiff as the closed loop is
fast divided by the speed, so steps in s proportional to the speed keep RK4 equally accurate
at 0.5 m/s and at 8 m/s. The plan's tables (nominal and gains) hold those nodes and the
midpoints in s between them, where RK4 evaluates A(s) and B(s) anyway: the nominal and the
linearization are computed once, on that grid, and P at a midpoint is the cubic Hermite
interpolant of its two nodes with the exact slopes ``P' = -F(P)`` (error O(h^4), as RK4's).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path as FilePath
from typing import NamedTuple

import numpy as np

from ..config.controller import ControllerParams
from ..config.maneuver import ManeuverSpec, load_maneuver, load_maneuver_text
from ..config.vehicle import VehicleParams
from ..control.actuator import augmented_jacobians
from ..control.attitude_table import NominalAttitudes
from ..control.riccati import SweepDivergence, care, periodic_riccati, riccati_rhs, sweep_backward
from ..control.transverse import transverse_jacobians
from ..blas import one_blas_thread
from ..errors import ManeuverError
from ..geometry.build import build_path
from ..geometry.path import Path
from ..model.mixer import Mixer
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import rpy_to_matrix
from .cache import PlanCache, default_cache
from .diagnose import euler_singularity, explain_divergence
from .feasibility import Feasibility, check_feasibility
from .budget import check_budget
from .flatness import FlatnessError, flat_nominal
from .layout import build_profiles, segment_ends, segment_starts
from .plan_entry import PlanEntry
from .profiles import Profile

__all__ = ["Plan", "plan_spec", "plan_cached", "plan_file", "plan_text", "segment_starts", "segment_ends",
           "build_profiles"]


@dataclass(frozen=True)
class Plan:
    """A planned maneuver: nominal x(s), u(s), gains K(s) on a common grid of s.

    ``dx`` is dx/ds = f(x, u)/v, used for Hermite interpolation of the nominal. ``K`` is
    (N, 4, 11) for the paper's design, or (N, 4, 15) when the rotor lag is in the design
    (``rotor_time_constant_s`` > 0): the last four columns act on the achieved wrench's
    deviation from the nominal (:mod:`mavreg.control.actuator`).
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
    """Served by the plan cache (:mod:`mavreg.maneuver.cache`) rather than planned now."""

    def nominal_attitude(self, s: float) -> np.ndarray:
        """Rbar(s) (3, 3) between the grid rows around s (clamped), by the cubic in the
        rotation vector of :class:`~mavreg.control.attitude_table.NominalAttitudes`."""
        s = float(np.clip(s, self.s[0], self.s[-1]))
        i = int(np.clip(np.searchsorted(self.s, s) - 1, 0, len(self.s) - 2))
        rows = slice(i, i + 2)
        R = (self.R[rows] if self.R is not None
             else np.moveaxis(rpy_to_matrix(*self.x[rows, 3:6].T), -1, 0))
        table = NominalAttitudes(self.s[rows], R, self.x[rows, 9:12] / self.speed_m_s[rows, None])
        return table.at(0, (s - self.s[i]) / (self.s[i + 1] - self.s[i]))

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
        s = float(np.clip(s, self.s[0], self.s[-1]))
        i = int(np.clip(np.searchsorted(self.s, s) - 1, 0, len(self.s) - 2))
        h = self.s[i + 1] - self.s[i]
        u = (s - self.s[i]) / h
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


def _time_grid(path: Path, speed: Profile, step_s: float) -> np.ndarray:
    """Arc lengths evenly spaced in nominal time, step_s apart (last node at the end)."""
    s_fine = path.s_nodes
    v = speed.evaluate(s_fine)[0]
    if np.min(v) <= 0:
        raise ManeuverError(f"speed profile reaches {np.min(v):.3f} m/s: it must stay positive")
    t_fine = np.concatenate([[0.0], np.cumsum(np.diff(s_fine) * (1 / v[1:] + 1 / v[:-1]) / 2)])
    n = max(2, int(np.ceil(t_fine[-1] / step_s)) + 1)
    return np.interp(np.linspace(0.0, t_fine[-1], n), t_fine, s_fine)


def _with_midpoints(nodes: np.ndarray) -> np.ndarray:
    """Nodes at the even indices, the midpoints in s between them at the odd ones."""
    s = np.empty(2 * len(nodes) - 1)
    s[0::2] = nodes
    s[1::2] = (nodes[:-1] + nodes[1:]) / 2
    return s


class _Nominal(NamedTuple):
    """The nominal on a grid: path frames F, curvature k, state x, input u, dx = x'(s),
    speed v and attitude R."""

    F: np.ndarray
    k: np.ndarray
    x: np.ndarray
    u: np.ndarray
    dx: np.ndarray
    v: np.ndarray
    R: np.ndarray


def _nominal(model, path, speed, yaw, s, yaw_mode: str) -> _Nominal:
    c, F, k, dk, ddk = path.evaluate(s)
    v4 = speed.evaluate(s)
    try:
        x, u, R = flat_nominal(model, F, k, dk, ddk, c, v4, yaw.evaluate(s), yaw_mode)
    except FlatnessError as exc:
        q = float(s[exc.index])
        raise ManeuverError(f"nominal: {exc.what} at s = {q:.2f} m in "
                            f"{path.segment_at(q).name!r} (yaw mode {yaw_mode}): {exc.remedy}") from None
    _check_attitude_continuity(s, R, x[:, 9:12], v4[0], path, yaw_mode)
    with np.errstate(all="ignore"):      # roll-pitch-yaw rates are singular at pitch +-90 deg
        dx = model.f(x.T, u.T).T / v4[0][:, None]
    dx[:, 3:6] = np.where(np.isfinite(dx[:, 3:6]), dx[:, 3:6], 0.0)
    return _Nominal(F, k, x, u, dx, v4[0], R)


_MAX_TURN_BETWEEN_SAMPLES_RAD = 0.2


def _check_attitude_continuity(s, R, omega, v, path, yaw_mode: str) -> None:
    """Refuse a nominal whose attitude jumps between two samples.

    Where the nose reference crosses the thrust axis (fixed yaw in a loop flown in the
    reference's plane) or the path's heading reverses (tangent yaw through the vertical), the
    flat map's attitude flips by 180 deg about the thrust axis between two samples; the body
    rates at the samples do not show it, the turn between them does. A turn larger than
    ``_MAX_TURN_BETWEEN_SAMPLES_RAD`` and than 3 times the body rate over the sample interval
    is such a jump.
    """
    if len(s) < 2:
        return
    cos_turn = (np.einsum("nji,nji->n", R[:-1], R[1:]) - 1.0) / 2.0
    turn = np.arccos(np.clip(cos_turn, -1.0, 1.0))
    dt = np.diff(s) / ((v[:-1] + v[1:]) / 2)
    rate = np.maximum(np.linalg.norm(omega[:-1], axis=1), np.linalg.norm(omega[1:], axis=1))
    jump = (turn > _MAX_TURN_BETWEEN_SAMPLES_RAD) & (turn > 3.0 * rate * dt)
    if np.any(jump):
        i = int(np.argmax(jump))
        q = float(s[i])
        raise ManeuverError(
            f"nominal: the attitude flips by {np.degrees(turn[i]):.0f} deg at s = {q:.2f} m in "
            f"{path.segment_at(q).name!r} (yaw mode {yaw_mode}): the nose reference crosses the "
            "thrust axis there (or the path's heading reverses); use yaw mode velocity for a "
            "loop flown nose-first, or another yaw")


class _Stopwatch:
    """Seconds spent in each stage, added into ``timings`` (a dict, or None: not kept)."""

    def __init__(self, timings: dict | None):
        self.timings = timings
        self._t0 = self._last = time.perf_counter()

    def lap(self, stage: str) -> None:
        if self.timings is not None:
            now = time.perf_counter()
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
    nominal: _Nominal
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
    s = _with_midpoints(_time_grid(path, speed, controller.riccati_step_s))
    clock.lap("path")
    nominal = _nominal(model, path, speed, yaw, s, spec.yaw.mode)
    rotors = nominal.u @ mixer.inverse.T
    feas = check_feasibility(s, nominal.u, rotors, nominal.v, vehicle.max_rotor_thrust_n,
                             spec.limits.min_speed_m_s, lambda q: path.segment_at(q).name,
                             nominal.R, spec.limits.max_tilt_rad)
    clock.lap("nominal")
    return _Stage(spec, vehicle, model, path, speed, yaw, s, nominal, rotors, feas)


def plan_spec(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
              strict: bool = True, *, timings: dict | None = None) -> Plan:
    """Plan a loaded maneuver.

    With ``strict``, an infeasible nominal raises :class:`ManeuverError` naming where and
    by how much; otherwise the plan is returned with ``feasibility.feasible`` False (and
    no gains are computed for an infeasible plan: ``K`` is zeros). ``timings``: a dict to
    receive the seconds spent on the ``path`` (with the profiles and the grid), the
    ``nominal`` (with its feasibility), the ``linearization``, the ``riccati`` sweep, and
    the ``total``.
    """
    clock = _Stopwatch(timings)            # from here: the thread limit's set-up is counted
    check_budget(spec, controller.riccati_step_s)      # before anything is allocated
    with one_blas_thread():
        return _plan_spec(spec, vehicle, controller, strict, clock)


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
        K, terminal = _gains(st.model, path, st.speed, st.yaw, s, controller, spec, tau, nominal, clock)
    except SweepDivergence as exc:
        k = nominal.k
        pitch = np.zeros(len(s)) if so3 else x[:, 4]     # no singularity in the SO(3) form
        raise ManeuverError(f"maneuver {spec.name!r}: " + explain_divergence(
            exc.s_m, s, pitch, v, st.rotors, vehicle.max_rotor_thrust_n, np.hypot(k[:, 0], k[:, 1]),
            lambda q: path.segment_at(q).name) + f" ({exc})") from None
    return st.plan(K, terminal, tau, controller.attitude_error)


def _du_ds(u: np.ndarray, s: np.ndarray, periodic: bool) -> np.ndarray:
    """du/ds on the grid s (second order, non-uniform)."""
    du = np.gradient(u, s, axis=0, edge_order=2)
    if periodic:      # the first and last points are the same point of the lap
        du[0] = du[-1] = (u[1] - u[-2]) / (s[1] - s[0] + s[-1] - s[-2])
    return du


def _first_of_runs(rows: np.ndarray, rtol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the rows that differ from the row before (beyond ``rtol`` of each column's
    scale), and for every row the index of its run's first row among them."""
    scale = np.maximum(np.abs(rows).max(axis=0), 1.0)
    new = np.ones(len(rows), dtype=bool)
    new[1:] = (np.abs(np.diff(rows, axis=0)) > rtol * scale).any(axis=1)
    return np.flatnonzero(new), np.cumsum(new) - 1


def _linearization(model, tau: float, nominal: _Nominal, s, periodic: bool = False,
                   so3: bool = False):
    """(A, B) on the grid ``s`` of ``nominal`` (:func:`_nominal`), augmented with the rotor
    lag when ``tau`` > 0; the attitude error on SO(3) with ``so3``, else the paper's
    roll-pitch-yaw differences.

    A and B depend on the nominal through everything but its position; where that is the
    same from one grid point to the next (a straight line flown at constant speed and
    heading: a maneuver's run-up and its slow ends), they are computed once for the run.
    """
    F, k, x, u, dx, v, R = nominal
    du = _du_ds(u, s, periodic)
    rows = np.concatenate([F.reshape(len(s), -1), R.reshape(len(s), -1), k, x[:, 3:], u, dx[:, 3:],
                           v[:, None], du], axis=1)
    first, run = _first_of_runs(rows)
    pick = (F[first], k[first], x[first], u[first], dx[first])
    Rbar = R[first] if so3 else None
    if tau <= 0:
        A, B = transverse_jacobians(model, *pick, Rbar=Rbar)
    else:
        A, B = augmented_jacobians(model, tau, *pick, du[first], v[first], Rbar=Rbar)
    return A[run], B[run]


def _gains_on_grid(A, B, s, Q, R, P_T=None, periodic: bool = False):
    """K (and P) on the grid ``s`` of nodes and midpoints (:func:`_with_midpoints`) from
    A(s), B(s) there: RK4 through the nodes, cubic Hermite at the midpoints. ``P_T``: P at
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
    for a in range(0, len(Pn) - 1, _BLOCK_NODES):
        b = min(a + _BLOCK_NODES, len(Pn) - 1)
        dP = -riccati_rhs(An[a:b + 1], Bn[a:b + 1] @ Rinv_Bt[2 * a:2 * b + 1:2], Q, Pn[a:b + 1])
        P[2 * a + 1:2 * b:2] = ((Pn[a:b] + Pn[a + 1:b + 1]) / 2
                                + h[a:b, None, None] / 8 * (dP[:-1] - dP[1:]))
    for a in range(0, len(s), 2 * _BLOCK_NODES):
        np.matmul(Rinv_Bt[a:a + 2 * _BLOCK_NODES], P[a:a + 2 * _BLOCK_NODES], out=K[a:a + 2 * _BLOCK_NODES])
    return P, K


_BLOCK_NODES = 512


def _weights(controller: ControllerParams, tau: float) -> tuple[np.ndarray, np.ndarray]:
    q = controller.q if tau <= 0 else np.concatenate([controller.q, controller.q_wrench])
    return np.diag(q), np.diag(controller.r)


def _gains(model, path, speed, yaw, s, controller, spec, tau, nominal, clock: _Stopwatch):
    Q, R = _weights(controller, tau)
    A, B = _linearization(model, tau, nominal, s, so3=controller.attitude_error == "so3")
    clock.lap("linearization")
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
        _, K = _gains_on_grid(A, B, s, Q, R, P_T)
    except SweepDivergence:
        raise
    except ValueError as exc:
        raise ManeuverError(f"gain schedule: {exc}") from None
    clock.lap("riccati")
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
    grid = _with_midpoints(np.linspace(s0, s1, n))
    A, B = _linearization(model, tau, _nominal(model, path, speed, yaw, grid, yaw_mode), grid,
                          periodic=True, so3=controller.attitude_error == "so3")
    P, _ = _gains_on_grid(A, B, grid, Q, R, periodic=True)
    return P[-1]


def plan_cached(spec: ManeuverSpec, vehicle: VehicleParams, controller: ControllerParams,
                strict: bool = True, cache: PlanCache | None = None) -> Plan:
    """:func:`plan_spec` through ``cache`` (None: plan without one).

    The cache keeps a :class:`~mavreg.maneuver.plan_entry.PlanEntry` (the gains, a tenth
    of the plan's size); a hit computes the path and the nominal again, bit for bit as
    planning does, and puts the stored gains on them.
    """
    if cache is None:
        return plan_spec(spec, vehicle, controller, strict)
    fresh = []

    def build() -> PlanEntry:
        fresh.append(plan_spec(spec, vehicle, controller, strict))
        return PlanEntry.of(fresh[0])

    entry = cache.get_or_plan((spec, vehicle, controller, strict), build)
    if fresh:
        return fresh[0]
    st = _stage(spec, vehicle, controller, _Stopwatch(None)) if isinstance(entry, PlanEntry) else None
    try:
        K = entry.gain_table() if st is not None and entry.gains_shape[0] == len(st.s) else None
    except Exception:          # a damaged entry (zlib, shape): planned again, as an unreadable one
        K = None
    if K is None:
        return plan_spec(spec, vehicle, controller, strict)
    return replace(st.plan(K, entry.terminal, entry.rotor_time_constant_s, controller.attitude_error),
                   from_cache=True)


def plan_file(path: str | FilePath, vehicle: VehicleParams, controller: ControllerParams,
              laps: int | None = None, strict: bool = True, use_cache: bool = True) -> Plan:
    """Load and plan a maneuver YAML file (through :func:`~mavreg.maneuver.cache.default_cache`
    with ``use_cache``)."""
    spec = load_maneuver(path)
    if laps is not None:
        spec = spec.with_laps(laps)
    return plan_cached(spec, vehicle, controller, strict, default_cache() if use_cache else None)


def plan_text(text: str, source: str, vehicle: VehicleParams, controller: ControllerParams,
              strict: bool = True, use_cache: bool = True) -> Plan:
    """Load and plan maneuver YAML text (an upload); errors name ``source``."""
    return plan_cached(load_maneuver_text(text, source), vehicle, controller, strict,
                       default_cache() if use_cache else None)
