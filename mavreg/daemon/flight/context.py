"""What the supervisor's parts share: the flight's state and the flight's parts (no logic).

- :class:`FlightContext`: the mutable state of one flight, read and written by the phase
  handlers (:mod:`mavreg.daemon.flight.handlers`, :mod:`mavreg.daemon.flight.hover_phases`), the safety
  policy (:mod:`mavreg.daemon.flight.safety`), the messages in (:mod:`mavreg.daemon.flight.inbox`) and
  the supervisor (:mod:`mavreg.daemon.flight.supervisor`) through :class:`mavreg.daemon.flight.verbs.Flight`.
  Its fields are grouped by owner where that reads better (:class:`Heard`, :class:`Commands`,
  :class:`Landing`, :class:`RecoveryState`, :class:`ExcitationState`); each field's docstring names
  the module that writes it (``Writer:``), or the modules that share it and why (``Writers: ...;
  shared: ...``): ``tests/unit/test_flight_context.py`` holds the source to it.
- :class:`FlightParts`: the collaborators each flight is built of (controllers, monitor,
  gate, timing, output), made once by :meth:`FlightParts.build`.

Two clocks, named by domain in every field: ``*_vehicle_s`` is the vehicle's time
(``time_boot_ms`` of its samples: spool-up, ramps, holds, command retries; a lockstep emulator
flies the same flight at any speed); ``*_wall_s`` is the injected monotonic clock of the
daemon (link health, the forced-disarm retries). A vehicle that reboots on the ground starts its
clock again: :meth:`FlightContext.after_reboot` is a fresh context that keeps only what
survives it, stated there in one place.
"""
from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, NamedTuple

from ...config.defaults import CONTROL_RATE_HZ
from ...config.envelope import EnvelopeParams
from ...config.vehicle import VehicleParams
from ...control.estimation.forecast import Forecast, Forecaster
from ...control.controllers.hover import HoverController, Ramp
from ...control.controllers.recovery import RecoveryController
from .delays import ActuationDelay
from .excitation import RateStep
from .gate import HealthGate, NominalPoints
from ..vehicle.messages import VehicleStatus
from .monitor import EnvelopeMonitor
from .output import RateOutput, RotorOutput, command_output
from ..vehicle.peers import VehicleIds
from .phases import Counters, Phase, SupervisorParams
from .preflight import AutopilotSetup
from .reboot import RebootDetector
from .records import Outcome
from .state import StateAssembler, StateSample
from ..vehicle.timesync import TimesyncEstimator

if TYPE_CHECKING:
    from ...control.controllers.regulator import ManeuverRegulator
    from ...maneuver.plan import Plan

__all__ = ["Queued", "Flying", "DescentPoint", "Heard", "Commands", "Landing", "RecoveryState",
           "ExcitationState", "FlightContext", "FlightParts"]


class Queued(NamedTuple):
    """A maneuver accepted and queued, not yet flown."""

    plan: Plan
    regulator: ManeuverRegulator
    points: NominalPoints
    """Its nominal path, sampled once for the envelope's checks (:func:`~mavreg.daemon.flight.gate.nominal_points`)."""


class Flying(NamedTuple):
    """The maneuver in run-in or maneuver."""

    plan: Plan
    regulator: ManeuverRegulator


class DescentPoint(NamedTuple):
    """One sample of the landing's last second (:func:`~mavreg.daemon.flight.hover_phases.touched_down`)."""

    t_vehicle_s: float
    down_m_s: float
    """NED down velocity (descending: positive)."""


@dataclass
class Heard:
    """What the vehicle said in its current boot: all forgotten when it reboots."""

    status: VehicleStatus | None = None
    """Its last HEARTBEAT (None: none yet). Writer: inbox."""
    landed_state: int | None = None
    """Its MAV_LANDED_STATE (EXTENDED_SYS_STATE; None: none heard). Writer: inbox."""
    last_sample: StateSample | None = None
    """The last complete state sample. Writer: supervisor."""
    last_sample_wall_s: float | None = None
    """When it came (injected clock). Writer: supervisor."""
    forecast: Forecast | None = None
    """The last sample predicted across the delay: the state the controllers act on. Writer: verbs."""
    stream_start_vehicle_s: float | None = None
    """The first sample's time on the ground: the idle stream began (None: not streaming). Writer: handlers."""


@dataclass
class Commands:
    """The commands asked of the vehicle and their retries."""

    last_command_vehicle_s: float = -math.inf
    """When the last ARM / DO_SET_MODE / DISARM went out (retries). Writer: verbs."""
    arm_requested: bool = False
    """An ARM request went out (a refusal on the ground then sends one more disarm). Writer: handlers."""
    ground_end_wall_s: float | None = None
    """The flight began to end on the ground with the vehicle armed (None: it has not). Writer: safety."""
    terminate_start_wall_s: float = 0.0
    """The forced disarm began (motors stopped after an impact). Writer: safety."""
    disarm_sent_wall_s: float = -math.inf
    """The last forced disarm went out (its retries). Writer: safety."""


@dataclass
class Landing:
    """The landing asked for, and its touchdown."""

    requested: bool = False
    """Land after the current maneuver, or end on the ground before take-off.
    Writers: supervisor, handlers, safety; shared: a land request (supervisor), a takeover told to
    land (handlers) and a flight ending on the ground (safety) each ask for it."""
    mode_requested: bool = False
    """The autopilot's own landing mode was asked for after touchdown. Writer: hover_phases."""
    descent: collections.deque[DescentPoint] = field(default_factory=collections.deque)
    """The last second before touchdown (appended by ``touched_down``). Writer: hover_phases."""
    touchdown_speed_m_s: float | None = None
    """The fastest descent of the second before touchdown (None: not touched down). Writer: hover_phases."""
    spool_down_start_vehicle_s: float | None = None
    """Touchdown: the rotors spool down from here (None: not touched down). Writer: hover_phases."""


@dataclass
class RecoveryState:
    """The recovery controller's flights."""

    count: int = 0
    """Recoveries begun. Writer: safety."""
    landing: bool = False
    """The recovery controller is landing the vehicle (phase LAND). Writer: safety."""
    noted_bounds: set[str] = field(default_factory=set)
    """Bounds already announced while the recovery controller flies. Writer: safety."""
    settled_since_vehicle_s: float | None = None
    """Level, slow and at its altitude since (None: not settled).
    Writers: handlers, safety; shared: the recover handler times the settling, and a recovery
    begun (safety) starts it from unsettled."""


@dataclass
class ExcitationState:
    """The identification excitation (:mod:`mavreg.daemon.flight.excitation`), flown once per flight."""

    start_vehicle_s: float | None = None
    """It began (None: not yet, or none asked for). Writer: hover_phases."""
    end_vehicle_s: float | None = None
    """It ended, finished or cut short (None: not yet).
    Writers: hover_phases, verbs; shared: the hold ends it, and any change of phase cuts it short."""
    rate_step: RateStep | None = None
    """The rate the hold's excitation puts on the next rate command (None: none).
    Writers: hover_phases, verbs; shared: the hold sets it each sample, and a change of phase clears it."""


@dataclass
class FlightContext:
    """The state of one flight that the supervisor's parts share (see the module docstring)."""

    phase: Phase = Phase.PREFLIGHT
    """Writer: verbs."""
    reason: str = ""
    """Why the flight ended early (aborted, refused), in one line.
    Writers: verbs, safety; shared: an abort keeps its first detail, a hand-over states its own."""
    failure: Outcome | None = None
    """The first bound violated, with every action taken since (None: none yet). Writer: verbs."""
    actions: list[str] = field(default_factory=list)
    """Every safety action taken, in order (the outcome's ``action``). Writer: verbs."""
    statustext_id: int = 0
    """The last STATUSTEXT's id. Writer: verbs."""
    now_wall_s: float = 0.0
    """The injected clock at the message, tick or gap being handled. Writer: supervisor."""
    last_tick_wall_s: float | None = None
    """The last tick (a late one: this process was stalled). Writer: supervisor."""
    phase_start_vehicle_s: float = 0.0
    """The phase began. Writer: verbs."""
    gate_wait_start_vehicle_s: float | None = None
    """The health gate first failed in this hold (None: it has not).
    Writers: verbs, hover_phases, safety; shared: the hold starts the wait, a new hold or run-in
    (verbs, hover_phases) and a refusal (safety) end it."""

    pending: list[Queued] = field(default_factory=list)
    """Queued, not yet flown: queued, taken and dropped through the verbs (``queue``, ``start_next``,
    ``drop_pending``). Writer: verbs."""
    active: Flying | None = None
    """In run-in or maneuver (None: none): ``start_next``, ``end_maneuver``. Writer: verbs."""
    maneuvers_done: list[str] = field(default_factory=list)
    """The names of the maneuvers flown to their end (``end_maneuver``). Writer: verbs."""
    s_m: float = math.nan
    """Arc length in the maneuver (NaN elsewhere). Writers: handlers, hover_phases, safety; shared:
    the maneuver handler sets it each sample; the run-in starts it; leaving a maneuver (recovered,
    landing, a safety action) clears it."""
    ramps: list[Ramp] = field(default_factory=list)
    """The hover references still to fly (take-off, hold, run-in, landing), the first one current.
    Writer: verbs."""
    ramp_start_vehicle_s: float = 0.0
    """The current ramp began. Writer: verbs."""
    ground_z_m: float = 0.0
    """NED down of the take-off point. Writer: handlers."""

    heard: Heard = field(default_factory=Heard)
    commands: Commands = field(default_factory=Commands)
    landing: Landing = field(default_factory=Landing)
    recovery: RecoveryState = field(default_factory=RecoveryState)
    excitation: ExcitationState = field(default_factory=ExcitationState)

    def after_reboot(self) -> FlightContext:
        """A fresh context that keeps what survives the vehicle's reboot on the ground
        (:mod:`mavreg.daemon.flight.reboot`): the flight's own state. What is keyed to the old boot
        is new: all it said (:class:`Heard`), every ``*_vehicle_s`` (its clock started again), the
        arm request and the ground disarm's wait. A field added later is new unless kept here."""
        c, land, rec = self.commands, self.landing, self.recovery
        return FlightContext(
            phase=self.phase, reason=self.reason, failure=self.failure, actions=self.actions,
            statustext_id=self.statustext_id, now_wall_s=self.now_wall_s, last_tick_wall_s=self.last_tick_wall_s,
            pending=self.pending, active=self.active, maneuvers_done=self.maneuvers_done, s_m=self.s_m,
            ramps=self.ramps, ground_z_m=self.ground_z_m,
            commands=Commands(terminate_start_wall_s=c.terminate_start_wall_s, disarm_sent_wall_s=c.disarm_sent_wall_s),
            landing=Landing(requested=land.requested, mode_requested=land.mode_requested, descent=land.descent,
                            touchdown_speed_m_s=land.touchdown_speed_m_s),
            recovery=RecoveryState(count=rec.count, landing=rec.landing, noted_bounds=rec.noted_bounds),
            excitation=ExcitationState(rate_step=self.excitation.rate_step))

    @property
    def vehicle_now_s(self) -> float:
        """The vehicle's time of the last sample (NaN before the first)."""
        s = self.heard.last_sample
        return s.time_s if s is not None else math.nan


@dataclass(frozen=True)
class FlightParts:
    """The collaborators of one flight (see :class:`mavreg.daemon.flight.supervisor.Supervisor` for
    the parameters)."""

    vehicle: VehicleParams
    params: SupervisorParams
    envelope: EnvelopeParams
    regulator_factory: Callable
    timesync: TimesyncEstimator
    forecaster: Forecaster
    hover: HoverController
    recovery: RecoveryController
    monitor: EnvelopeMonitor
    assembler: StateAssembler
    output: RotorOutput | RateOutput
    delay: ActuationDelay
    gate: HealthGate
    autopilot: AutopilotSetup
    counters: Counters
    ids: VehicleIds
    """The vehicle's system and component id (pinned, or fixed by its first autopilot HEARTBEAT):
    every command and set-point is addressed to :attr:`VehicleIds.target`."""
    reboots: RebootDetector
    """Sees the vehicle reboot (:mod:`mavreg.daemon.flight.reboot`)."""

    @classmethod
    def build(cls, vehicle: VehicleParams, params: SupervisorParams, regulator_factory,
              envelope: EnvelopeParams | None = None,
              link_health: Callable[[], tuple[float, float] | None] | None = None,
              forecaster: Forecaster | None = None, fixed_delay_s: float | None = None) -> FlightParts:
        """The parts of a flight with these parameters (defaults as the supervisor's)."""
        timesync = TimesyncEstimator()
        if forecaster is None:
            forecaster = Forecaster(vehicle, 1.0 / CONTROL_RATE_HZ, predict=False)
        envelope = envelope if envelope is not None else EnvelopeParams()
        ids = VehicleIds(params.vehicle_system_id, params.vehicle_component_id)
        output = command_output(vehicle, ids, forecaster.rotor_lag)
        delay = ActuationDelay(timesync, vehicle, output.kind, fixed_delay_s)
        return cls(
            vehicle=vehicle, params=params, envelope=envelope, regulator_factory=regulator_factory,
            timesync=timesync, forecaster=forecaster,
            hover=HoverController(vehicle, params.hover),
            recovery=RecoveryController(vehicle, envelope.recovery),
            monitor=EnvelopeMonitor(envelope, vehicle.mass_kg, vehicle.max_rotor_thrust_n),
            assembler=StateAssembler(params.euler_pitch_limit_rad),
            output=output, delay=delay,
            gate=HealthGate(envelope, vehicle.mass_kg, vehicle.max_rotor_thrust_n,
                            link_health if link_health is not None else delay.measured_link),
            autopilot=AutopilotSetup(ids, params.telemetry_rate_hz, params.parameter_timeout_s,
                                     choice=vehicle.dialect, output=vehicle.output),
            counters=Counters(), ids=ids, reboots=RebootDetector(params.reboot_back_s))
