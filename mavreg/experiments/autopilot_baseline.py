"""The autopilot's own position controller as a baseline: the plan's nominal as timed set-points.

Maneuver regulation is compared with what a PX4 or ArduCopter user flies first: the same path
and speed profile handed to the autopilot's position controller as ``SET_POSITION_TARGET_LOCAL_NED``
(position, velocity, acceleration feed-forward, yaw and yaw rate; ``MAV_FRAME_LOCAL_NED``) at
a fixed rate, in OFFBOARD or GUIDED (``scripts/compare_autopilots.py``).

Nothing here re-derives the nominal. The plan's nominal is timed by its speed profile,
``ds/dt = v(s)``, by :class:`mavreg.trackers.timed.TimedNominal` (what the time-indexed trackers
of ``mavreg experiment gust|lag`` fly); the take-off, the hold, the run-in onto the entry state
and the stop at the exit are the daemon's own ramps (:mod:`mavreg.daemon.flight.flightpath`), so the
autopilot flies the maneuver from the same entry as mavreg does. :class:`BaselineSchedule` is
that whole reference as one function of time, phase by phase. Pure numbers: no clock, no I/O.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ..control.controllers.hover import HoverParams, Ramp
from ..daemon.flight import flightpath as fp
from ..model.rotation import rpy_to_matrix, wrap_angle
from ..trackers.timed import TimedNominal

__all__ = ["Setpoint", "Phase", "BaselineSchedule", "nominal_setpoint", "TYPE_MASK_POS_VEL_ACC_YAW",
           "SETPOINT_RATE_HZ", "MANEUVER", "FEEDFORWARDS"]

TYPE_MASK_POS_VEL_ACC_YAW = 0
"""``SET_POSITION_TARGET_LOCAL_NED.type_mask`` with nothing ignored: position, velocity,
acceleration (bit 9 clear: an acceleration, not a force), yaw and yaw rate all used."""
SETPOINT_RATE_HZ = 50.0
"""The set-point stream's rate (PX4 needs more than 2 Hz in OFFBOARD; its position
controller runs at the estimator's 50 Hz... 100 Hz)."""
MANEUVER = "maneuver"
"""The phase judged: the nominal flown in time."""
FEEDFORWARDS = ("kinematic", "thrust")
"""The acceleration fed forward on the maneuver: ``kinematic``, the nominal position's second
derivative (what the message's field means); ``thrust``, what the nominal's thrust alone gives,
gravity added (the kinematic one less the nominal's drag): an autopilot that models no drag
(PX4, ArduCopter) turns it into the nominal's thrust and tilt, as mavreg's plan has them."""


class Setpoint(NamedTuple):
    """One set-point (NED, SI units; yaw wrapped to (-pi, pi])."""

    phase: str
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    accel_m_s2: np.ndarray
    yaw_rad: float
    yaw_rate_rad_s: float


@dataclass(frozen=True)
class Phase:
    """A piece of the schedule: ``sample(t)`` for ``0 <= t < duration_s`` of its own time."""

    name: str
    start_s: float
    duration_s: float
    sample: Callable[[float], tuple]

    @property
    def end_s(self) -> float:
        return self.start_s + self.duration_s


def nominal_setpoint(timed: TimedNominal, t_s: float, feedforward: str = "kinematic") -> tuple:
    """(position, velocity, acceleration NED, yaw, yaw rate) of the timed nominal at ``t_s``.

    The velocity is the nominal body velocity turned to NED; the acceleration the second time
    derivative of the nominal position (:meth:`TimedNominal.reference`: what the nominal's
    thrust and drag add up to), or with ``feedforward="thrust"`` the thrust's part of it,
    ``g e3 - (f / m) R e3`` (:data:`FEEDFORWARDS`); the yaw rate is the ZYX Euler rate of the
    nominal body rates."""
    ref = timed.reference(float(t_s))
    x = ref.x
    phi, theta, psi = (float(a) for a in x[3:6])
    R = rpy_to_matrix(phi, theta, psi)
    q, r = float(x[10]), float(x[11])
    yaw_rate = (q * math.sin(phi) + r * math.cos(phi)) / max(math.cos(theta), 1e-6)
    if feedforward == "thrust":
        model = timed.model
        accel = np.array([0.0, 0.0, model.g]) - (float(ref.u[0]) / model.mass_kg) * R[:, 2]
    else:
        accel = np.asarray(ref.acceleration_ned_m_s2, dtype=float)
    return np.asarray(x[:3], dtype=float), R @ x[6:9], accel, float(wrap_angle(psi)), float(yaw_rate)


def _ramp_phase(name: str, start_s: float, ramp: Ramp, duration_s: float | None = None) -> Phase:
    def sample(t: float) -> tuple:
        p, v, a, yaw, yaw_rate = ramp.sample(t)
        return np.asarray(p, float), np.asarray(v, float), np.asarray(a, float), float(wrap_angle(yaw)), yaw_rate
    return Phase(name, start_s, ramp.duration_s if duration_s is None else duration_s, sample)


class BaselineSchedule:
    """The whole reference of a baseline flight from ``start_m`` (where the vehicle is when the
    schedule starts: on the ground for a take-off in OFFBOARD, or in the air after ArduCopter's
    own take-off) to the hold at the exit.

    Phases: ``spool`` (``spool_s`` on the spot), ``climb`` (straight up to the hold altitude),
    ``transfer`` (to the hold point before the entry), ``hold`` (``hold_s``), ``run_in`` (the
    daemon's ramp onto the entry's position, velocity and acceleration), ``maneuver`` (the
    nominal in time, :attr:`maneuver_s` long, its acceleration as ``feedforward`` says), ``stop`` (the daemon's stop ramp from the exit)
    and ``exit_hold`` (``exit_hold_s``). After :attr:`duration_s` it holds the last point.
    """

    def __init__(self, plan, start_m, start_yaw_rad: float, hold_s: float = 3.0, exit_hold_s: float = 3.0,
                 spool_s: float = 1.0, run_in_m: float = 0.6, hover: HoverParams | None = None,
                 feedforward: str = "kinematic"):
        if feedforward not in FEEDFORWARDS:
            raise ValueError(f"feedforward must be one of {', '.join(FEEDFORWARDS)}, not {feedforward!r}")
        for name, value in (("hold_s", hold_s), ("exit_hold_s", exit_hold_s), ("spool_s", spool_s)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value}")
        start = np.asarray(start_m, dtype=float).reshape(-1)
        if start.shape != (3,) or not np.all(np.isfinite(start)):
            raise ValueError(f"start_m must be 3 finite NED coordinates, got {start_m!r}")
        hover = hover or HoverParams()
        self.feedforward = feedforward
        self.plan = plan
        self.timed = TimedNominal(plan)
        entry = fp.entry_of(plan, hover, run_in_m)
        sit, climb, transfer = fp.takeoff_ramps(start, float(start_yaw_rad), entry, spool_s, hover)
        phases: list[Phase] = []

        def add(name: str, ramp: Ramp, duration_s: float | None = None) -> None:
            start_s = phases[-1].end_s if phases else 0.0
            phases.append(_ramp_phase(name, start_s, ramp, duration_s))

        add("spool", sit)
        add("climb", climb)
        add("transfer", transfer)
        add("hold", fp.hold_ramp(entry.hold_m, entry.yaw_rad), hold_s)
        for ramp in fp.run_in_ramps(entry.hold_m, entry.yaw_rad, entry, hover):
            add("run_in", ramp)
        self.maneuver_start_s = phases[-1].end_s
        self.maneuver_s = float(self.timed.duration_s)
        phases.append(Phase(MANEUVER, self.maneuver_start_s, self.maneuver_s,
                            lambda t: nominal_setpoint(self.timed, t, feedforward)))
        p_end, v_end, _, yaw_end, _ = nominal_setpoint(self.timed, self.maneuver_s)
        stop = fp.stop_ramp(p_end, v_end, yaw_end, hover)
        add("stop", stop)
        add("exit_hold", fp.hold_ramp(stop.end_position_m, stop.end_yaw_rad), exit_hold_s)
        self.phases = tuple(phases)
        self.duration_s = phases[-1].end_s
        self.entry = entry

    @property
    def maneuver_window_s(self) -> tuple[float, float]:
        """(start, end) of the maneuver in schedule time."""
        return self.maneuver_start_s, self.maneuver_start_s + self.maneuver_s

    def phase_at(self, t_s: float) -> Phase:
        """The phase flown at schedule time ``t_s`` (the first before 0, the last after the end;
        a phase of no duration, the spool after an autopilot's own take-off, is never flown)."""
        for ph in self.phases:
            if t_s < ph.end_s and ph.duration_s > 0.0:
                return ph
        return self.phases[-1]

    def at(self, t_s: float) -> Setpoint:
        """The set-point at schedule time ``t_s``."""
        ph = self.phase_at(t_s)
        local = min(max(t_s - ph.start_s, 0.0), ph.duration_s)
        p, v, a, yaw, yaw_rate = ph.sample(local)
        return Setpoint(ph.name, p, v, a, yaw, yaw_rate)

    def sample_maneuver(self, step_s: float = 0.02) -> dict[str, np.ndarray]:
        """The maneuver's set-points every ``step_s``: ``t_s`` (from the maneuver's start),
        ``position_ned_m``, ``velocity_ned_m_s``, ``accel_ned_m_s2`` (for figures and checks)."""
        if not step_s > 0.0:
            raise ValueError(f"step_s must be positive, got {step_s}")
        t = np.arange(0.0, self.maneuver_s + 0.5 * step_s, step_s)
        rows = [nominal_setpoint(self.timed, float(ti), self.feedforward) for ti in t]
        return {"t_s": t, "position_ned_m": np.array([r[0] for r in rows]),
                "velocity_ned_m_s": np.array([r[1] for r in rows]),
                "accel_ned_m_s2": np.array([r[2] for r in rows])}
