"""The supervisor's vocabulary: phases, parameters, events, log records, counters (no logic).

The bound-violation and outcome records are in :mod:`mavreg.daemon.flight.records`.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

import numpy as np

from ...config.defaults import STALE_TIMEOUT_S
from ...control.controllers.hover import HoverParams
from .excitation import ExcitationParams

__all__ = ["Phase", "PHASE_CODES", "AIRBORNE", "FREE_FLIGHT", "SupervisorParams", "Event", "LogRecord",
           "Output", "Counters"]


class Phase(str, enum.Enum):
    """The flight's phases. A member is its name as a string (``Phase.HOLD == "hold"``, and so
    in f-strings, events, JSON and the control log); new phases go at the end (their log code
    is their position, :data:`PHASE_CODES`)."""

    __str__ = str.__str__
    __format__ = str.__format__

    PREFLIGHT = "preflight"
    TAKEOFF = "takeoff"
    HOLD = "hold"
    RUN_IN = "run_in"
    MANEUVER = "maneuver"
    LAND = "land"
    DISARMED = "disarmed"
    ABORTED = "aborted"
    RECOVER = "recover"
    """The recovery controller levels, brakes, climbs and holds."""
    TERMINATE = "terminate"
    """Motors stopped: forced disarm repeated until the vehicle reports disarmed; no stream."""
    TAKEOVER = "takeover"
    """The vehicle was found armed in the air (a restarted daemon, say): the recovery
    controller's set-points stream, matching the vehicle's state, until the autopilot grants
    OFFBOARD; then the recovery holds it (:class:`mavreg.daemon.flight.handlers.Takeover`)."""


PHASE_CODES = {p: i for i, p in enumerate(Phase)}
"""Integer codes of the phases in the controller log (new phases appended: old logs keep theirs)."""

AIRBORNE = frozenset({Phase.TAKEOFF, Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER, Phase.LAND, Phase.RECOVER})
"""Phases in which the daemon streams rotor commands to an armed vehicle in OFFBOARD: the one
set every part asks (the per-sample pipeline, the envelope monitor, the gap and link checks,
the daemon's signal handler through :attr:`Supervisor.airborne`)."""

FREE_FLIGHT = frozenset({Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER})
"""Airborne phases clear of the ground: the disturbance observer learns throughout them."""


AIRBORNE_CHOICES = ("land", "fly")
"""What a vehicle found armed in the air is taken over for (:attr:`SupervisorParams.airborne`)."""


@dataclass(frozen=True)
class SupervisorParams:
    """Identities, timeouts and flight-shape parameters (SI units)."""

    vehicle_system_id: int | None = 1
    """The vehicle's system id (1..255); None: taken from its first autopilot HEARTBEAT
    (:class:`mavreg.daemon.vehicle.peers.VehicleIds`; ``udpin:`` without ``--vehicle-system-id``)."""
    vehicle_component_id: int = 1
    stale_timeout_s: float = STALE_TIMEOUT_S
    reboot_back_s: float = 1.0
    """A state part this much older (vehicle time) than the newest one is a new boot's: the
    vehicle rebooted (:mod:`mavreg.daemon.flight.reboot`)."""
    """No complete sample for this long (injected clock) while armed: the link is lost, the
    stream stops for good and the vehicle's failsafe takes over (docs/safety.md, gaps)."""
    tick_stall_s: float = 0.05
    """A tick this much later than the previous one means the daemon's own process was
    stalled (samples may be waiting unread): that tick does not judge the link."""
    command_retry_s: float = 0.5
    """Vehicle time between repeats of an unanswered ARM / DO_SET_MODE / DISARM."""
    disarm_retry_s: float = 0.1
    """Injected-clock time between repeats of a forced disarm (it repeats until disarmed)."""
    terminate_timeout_s: float = 10.0
    """A forced disarm not confirmed within this (injected clock): give up, stream stopped.
    Long enough for a lockstep emulator to notice the stream has stopped (it waits
    ``--lockstep-timeout`` before running on) and deliver a delayed command."""
    timesync_wait_s: float = 2.0
    """Vehicle time from the first sample to wait for a TIMESYNC answer before arming. With no
    answer and no configured ``fixed_delay_s`` the link delay is unknown: the take-off is
    refused (the controller predicts across that delay, and the gate judges it)."""
    offboard_stream_min_s: float = 0.7
    """Vehicle time the idle stream runs before OFFBOARD is requested (vehicle needs 0.5 s)."""
    spool_s: float = 1.0
    """Smooth thrust spool-up before take-off and spool-down after touchdown."""
    hold_before_s: float = 1.0
    hold_after_s: float = 1.0
    run_in_m: float = 0.6
    """Distance of the hold point before the entry, along the entry velocity."""
    entry_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Experiments only (the paper's Section 4 starts 0.6 m off in each axis): the hold point
    and the run-in's end move by this NED offset, so the regulator takes over off the path
    with the entry's velocity. Zero in ordinary flight."""
    land_speed_m_s: float = 0.3
    land_slow_altitude_m: float = 0.4
    touchdown_band_m: float = 0.5
    """Touchdown is looked for within this height of the take-off point: an estimator's height
    over the same ground can move by tenths of a metre in a flight (PX4's EKF2 follows its
    barometer: 0.3 m measured), so the height alone cannot say the vehicle is down."""
    touchdown_stall_m_s: float = 0.1
    touchdown_settle_s: float = 0.25
    """Touchdown: within :attr:`touchdown_band_m`, the descent the landing asks for has stopped
    (every vertical speed below :attr:`touchdown_stall_m_s`, sinking, for this long): the
    ground holds the vehicle. Only then are the motors spooled down, so that an estimate that
    reads the ground too high never idles the motors in the air."""
    land_mode_after_s: float = 1.0
    """Vehicle time after the spool-down that disarm requests are tried; then the autopilot's
    own landing mode is asked for (its land detector disarms; ArduCopter refuses a disarm in
    GUIDED until it has detected the landing itself)."""
    ground_disarm_timeout_s: float = 1.0
    """Injected-clock time an armed vehicle has to report disarmed when the flight ends on the
    ground (a refusal before take-off, a land request); then the stream stops and the
    vehicle's failsafe is in charge, so a refusal ends ``fly`` within 2 s."""
    land_when_done: bool = True
    """Land after the last queued maneuver (``fly``); ``serve`` keeps holding."""
    airborne: str = "land"
    """A vehicle found armed in the air, not armed by this daemon (a restart after a crash): it
    is taken over and held where it is, then ``land`` (the queued maneuver is dropped) or
    ``fly`` (the queued maneuver is flown from the hold). It is never armed, disarmed or taken
    off then (docs/safety.md, *Taking over an airborne vehicle*)."""
    takeover_landed_state_wait_s: float = 1.5
    """Vehicle time an armed vehicle that sends no landed state (EXTENDED_SYS_STATE) is given:
    then it counts as airborne when it is more than ``touchdown_band_m`` above the estimate's
    origin, else as armed on the ground (refused)."""
    gap_fill: bool = True
    """A vehicle in real time: when a sample is more than 1.5 control periods late, command
    from the prediction of the last one (:meth:`Supervisor.fill_gap`), as far as the
    prediction horizon reaches. Off for a lockstep simulator, which waits for each command
    (an extra command there would answer a sample that has not been sent)."""
    lockstep: bool = False
    """The vehicle is a lockstep simulator: its time is the only clock that tells a gap (the
    wall clock does not pass while it runs ahead without commands, e.g. through a telemetry
    outage), so a gap of vehicle time alone is judged (docs/safety.md, *Gaps*)."""
    euler_pitch_limit_rad: float = math.radians(75.0)
    hover: HoverParams = field(default_factory=HoverParams)
    telemetry_rate_hz: float = 500.0
    """The attitude and position telemetry rate asked of the autopilot (SET_MESSAGE_INTERVAL;
    the control rate)."""
    parameter_timeout_s: float = 10.0
    """Vehicle time the autopilot may take to answer the parameter reads before arming
    (:mod:`mavreg.daemon.flight.preflight`); then the take-off is refused."""
    excitation: ExcitationParams | None = None
    """The identification flight's rate doublets in the hold before the first maneuver
    (``--identify-excitation``, :mod:`mavreg.daemon.flight.excitation`; the rates output only).
    None (the default): no excitation."""

    def __post_init__(self):
        if self.airborne not in AIRBORNE_CHOICES:
            raise ValueError(f"airborne must be one of {AIRBORNE_CHOICES}, not {self.airborne!r}")


@dataclass(frozen=True)
class Event:
    """A phase change or notable fact, stamped with vehicle time and arc length.

    ``time_s`` is the vehicle's time (NaN before its first sample); ``daemon_s`` the seconds
    since the daemon started (its injected clock), which every event has: the daemon stamps
    it (:class:`mavreg.daemon.jobs.app.Daemon`); NaN for a supervisor run without one (tests).
    """

    time_s: float
    kind: str
    phase: str
    s_m: float
    detail: str
    daemon_s: float = math.nan

    def line(self) -> str:
        """One line: the daemon's clock, the vehicle's (blank before its first sample), the rest."""
        s = "" if math.isnan(self.s_m) else f" s={self.s_m:.3f} m"
        d = "" if math.isnan(self.daemon_s) else f"daemon {self.daemon_s:8.3f} s  "
        t = f"vehicle t={self.time_s:8.3f} s" if math.isfinite(self.time_s) else " " * 20
        return f"{d}{t} [{self.phase}] {self.kind}{s}: {self.detail}"


@dataclass(frozen=True)
class LogRecord:
    """Controller internals of one control step."""

    time_s: float
    phase: str
    s_m: float
    w: np.ndarray
    u: np.ndarray
    rotor_cmd_n: np.ndarray
    """Rotor forces asked by the controller (unclipped)."""
    x: np.ndarray
    disturbance: tuple = (math.nan,) * 6
    """The disturbance observer's estimate (c_xy, c_z, F_n, F_e, F_d, thrust scale); NaN
    without an observer."""


@dataclass
class Output:
    messages: list = field(default_factory=list)
    events: list = field(default_factory=list)
    log: LogRecord | None = None
    taken: int | None = None
    """Of a read's messages (:meth:`Supervisor.handle_many`), how many this flight took: fewer
    than given when one of them ended it (the rest are the next flight's); None: all."""


@dataclass
class Counters:
    foreign_dropped: int = 0
    samples: int = 0
    actuator_sent: int = 0
    commands_sent: int = 0
    non_finite: int = 0
    acks: int = 0
    gaps: int = 0
    """Samples that came after a gap longer than ``EnvelopeParams.maneuver_gap_s``."""
    statustexts: int = 0
    gap_commands: int = 0
    """Commands sent from a prediction while a sample was late (:meth:`Supervisor.fill_gap`)."""
    timesync_dropped: int = 0
    """TIMESYNC replies that answered no request of ours, or implied an implausible delay."""
    unsupported_heartbeats: int = 0
    superseded: int = 0
    """Complete samples not answered because a newer one came in the same read of the link
    (:meth:`Supervisor.handle_many`): the daemon had fallen behind its telemetry."""
    reboots: int = 0
    """Reboots of the vehicle seen (its ``time_boot_ms`` went back, :mod:`mavreg.daemon.flight.reboot`)."""
    """HEARTBEATs of an autopilot mavreg does not speak to (:mod:`mavreg.daemon.flight.preflight`)."""
