"""What the supervisor's parts share: the flight's state and the flight's parts (no logic).

- :class:`FlightContext`: the mutable state of one flight, read and written by the phase
  handlers (:mod:`mavreg.daemon.flight.handlers`, :mod:`mavreg.daemon.flight.hover_phases`), the safety
  policy (:mod:`mavreg.daemon.flight.safety`) and the supervisor (:mod:`mavreg.daemon.flight.supervisor`)
  through :class:`mavreg.daemon.flight.verbs.Flight`.
- :class:`FlightParts`: the collaborators each flight is built of (controllers, monitor,
  gate, timing, output), made once by :meth:`FlightParts.build`.

Two clocks, named by domain in every field: ``*_vehicle_s`` is the vehicle's time
(``time_boot_ms`` of its samples: spool-up, ramps, holds, command retries; a lockstep emulator
flies the same flight at any speed); ``*_wall_s`` is the injected monotonic clock of the
daemon (link health, the forced-disarm retries).
"""
from __future__ import annotations

import collections
import dataclasses
import math
from dataclasses import dataclass, field
from typing import Callable

from ...config.defaults import CONTROL_RATE_HZ
from ...config.envelope import EnvelopeParams
from ...config.vehicle import VehicleParams
from ...control.estimation.forecast import Forecast, Forecaster
from ...control.controllers.hover import HoverController
from ...control.controllers.recovery import RecoveryController
from .delays import ActuationDelay
from .gate import HealthGate
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

__all__ = ["BOOT_KEYED", "FlightContext", "FlightParts"]

BOOT_KEYED_BESIDES_THE_CLOCK = ("vehicle_status", "landed_state", "last_sample", "last_sample_wall_s", "forecast",
                                "arm_requested", "ground_end_wall_s")
"""What the vehicle said or was asked in its last boot, beside its clock's fields."""


@dataclass
class FlightContext:
    """The state of one flight that the supervisor's parts share."""

    phase: Phase = Phase.PREFLIGHT
    reason: str = ""
    """Why the flight ended early (aborted, refused), in one line."""
    failure: Outcome | None = None
    """The first bound violated, with every action taken since (None: none yet)."""
    vehicle_status: VehicleStatus | None = None
    last_sample: StateSample | None = None
    forecast: Forecast | None = None
    """The last sample predicted across the delay: the state the controllers act on."""

    # the daemon's injected (wall, monotonic) clock
    now_wall_s: float = 0.0
    """The injected clock at the message, tick or gap being handled."""
    last_sample_wall_s: float | None = None
    last_tick_wall_s: float | None = None
    terminate_start_wall_s: float = 0.0
    disarm_sent_wall_s: float = -math.inf

    # the vehicle's clock
    stream_start_vehicle_s: float | None = None
    """The first sample's time: the idle stream began."""
    last_command_vehicle_s: float = -math.inf
    """When the last ARM / DO_SET_MODE / DISARM went out (retries)."""
    phase_start_vehicle_s: float = 0.0
    ramp_start_vehicle_s: float = 0.0
    spool_down_start_vehicle_s: float | None = None
    """Touchdown: the rotors spool down from here (None: not touched down)."""
    settled_since_vehicle_s: float | None = None
    """The recovery has been level, slow and at its altitude since (None: not settled)."""
    gate_wait_start_vehicle_s: float | None = None
    """The health gate first failed in this hold (None: it has not)."""
    excitation_start_vehicle_s: float | None = None
    """The identification excitation began (None: not yet, or none asked for)."""
    excitation_end_vehicle_s: float | None = None
    """It ended, finished or cut short (None: not yet); it is flown once per flight."""
    rate_excitation: tuple | None = None
    """(axis, rate rad/s) the hold's excitation puts on the next rate command (None: none)."""

    # the maneuvers
    pending: list = field(default_factory=list)
    """(plan, regulator, nominal points) queued, not yet flown."""
    active: tuple | None = None
    """(plan, regulator) in run-in or maneuver."""
    maneuvers_done: list = field(default_factory=list)
    s_m: float = math.nan
    """Arc length in the maneuver (NaN elsewhere)."""
    ramps: list = field(default_factory=list)
    """The hover references still to fly (take-off, hold, run-in, landing), the first one current."""
    ground_z_m: float = 0.0
    """NED down of the take-off point."""

    # the landing
    landed_state: int | None = None
    """The autopilot's MAV_LANDED_STATE (EXTENDED_SYS_STATE; None: none heard)."""
    land_requested: bool = False
    arm_requested: bool = False
    """An ARM request went out (a refusal on the ground then sends one more disarm)."""
    ground_end_wall_s: float | None = None
    """The flight began to end on the ground with the vehicle armed (None: it has not)."""
    land_mode_requested: bool = False
    descent: collections.deque = field(default_factory=collections.deque)
    """(vehicle time s, down velocity m/s) of the last 0.3 s before touchdown."""
    touchdown_speed_m_s: float | None = None

    # the safety actions
    recoveries: int = 0
    recovery_landing: bool = False
    """The recovery controller is landing the vehicle (phase LAND)."""
    noted_bounds: set = field(default_factory=set)
    """Bounds already announced while the recovery controller flies."""
    actions: list = field(default_factory=list)
    """Every safety action taken, in order (the outcome's ``action``)."""
    statustext_id: int = 0

    def forget_boot(self) -> None:
        """Set every field keyed to the vehicle's last boot back to its default: each
        ``*_vehicle_s`` (its clock started again) and :data:`BOOT_KEYED` (its status, samples
        and the requests it was sent). Used when it rebooted on the ground
        (:mod:`mavreg.daemon.flight.reboot`); a field added later on the vehicle's clock is covered
        by its name."""
        for f in dataclasses.fields(self):
            if f.name in BOOT_KEYED:
                setattr(self, f.name, f.default_factory() if f.default is dataclasses.MISSING else f.default)

    @property
    def vehicle_now_s(self) -> float:
        """The vehicle's time of the last sample (NaN before the first)."""
        return self.last_sample.time_s if self.last_sample is not None else math.nan


BOOT_KEYED = frozenset(f.name for f in dataclasses.fields(FlightContext)
                       if f.name.endswith("_vehicle_s") or f.name in BOOT_KEYED_BESIDES_THE_CLOCK)
"""The fields :meth:`FlightContext.forget_boot` resets."""


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
