"""The flight supervisor: sans-I/O flight phases of the mavreg daemon.

Decoded MAVLink messages and the current time go in (:meth:`Supervisor.handle`,
:meth:`Supervisor.tick`); messages to send, events and controller log records come out
(:class:`Output`). No sockets, no asyncio, no wall clock: the caller injects ``now_s``
(a monotonic clock for link health and the forced-disarm retries), while the flight's own
timing (spool-up, ramps, holds, command retries) runs on the vehicle's ``time_boot_ms``,
so a lockstep emulator flies the same flight at any speed.

Phases::

    preflight -> takeoff -> hold -> run_in -> maneuver -> hold (at exit) -> land -> disarmed
                             ^  (health gate)  |_________|   (next upload)
    takeoff..land --(bound violated)--> recover -> land (fly) | hold (serve)
    recover --(not settled in time)--> land (recovery controller) -> disarmed
    near the ground, or past max_recoveries --(bound violated)--> land (recovery controller)
    any armed --(impact: ground contact)--> terminate -> disarmed      (motors stopped)
    any armed --(link lost, non-finite output, vehicle left OFFBOARD)--> aborted

The supervisor is made of parts that share one flight (:class:`~mavreg.daemon.flight.verbs.Flight`:
the state in :class:`~mavreg.daemon.flight.context.FlightContext`, the collaborators in
:class:`~mavreg.daemon.flight.context.FlightParts`): one handler per phase
(:data:`mavreg.daemon.flight.handlers.HANDLERS`), the safety policy
(:class:`~mavreg.daemon.flight.safety.SafetyPolicy`), the messages in (:class:`~mavreg.daemon.flight.inbox.Inbox`),
the vocabulary in :mod:`mavreg.daemon.flight.phases` and the records in :mod:`mavreg.daemon.flight.records`.
This module takes the messages of a read and runs the per-sample pipeline (:meth:`Supervisor._on_sample`): gap policy, the envelope monitor on the
telemetry (:mod:`mavreg.daemon.flight.monitor`), the phase's control on the state from
:meth:`Flight.controller_state` (the one place a state predictor can be slotted in), the
monitor on the controller's errors, and the command out through :meth:`Flight.send_rotors`
(the one place every rotor command leaves). docs/safety.md states the envelope.
"""
from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Callable

import numpy as np

from ...config.envelope import EnvelopeParams
from ...config.vehicle import VehicleParams
from ...control.estimation.forecast import Forecaster
from ..vehicle import messages as mm
from .context import FlightContext, FlightParts, Queued
from .status import supervisor_status
from .excitation import check_output
from .verbs import Flight
from .gate import nominal_points
from .handlers import make_handlers
from .inbox import Inbox
from .phases import AIRBORNE, PHASE_CODES, Event, LogRecord, Output, Phase, SupervisorParams
from .reboot import STATE_PARTS
from .records import Outcome
from .safety import SafetyPolicy
from .state import StateSample

if TYPE_CHECKING:
    from ...control.controllers.hover import HoverController
    from ...control.controllers.recovery import RecoveryController
    from ..vehicle.peers import VehicleIds
    from ..vehicle.timesync import TimesyncEstimator
    from .delays import ActuationDelay
    from .gate import HealthGate
    from .monitor import EnvelopeMonitor
    from .output import RateOutput, RotorOutput
    from .phases import Counters
    from .preflight import AutopilotSetup
    from .reboot import RebootDetector
    from .state import StateAssembler

__all__ = ["Phase", "SupervisorParams", "Event", "LogRecord", "Output", "Supervisor", "PHASE_CODES",
           "Outcome"]


class Supervisor:
    """Flight phases around a hover LQR, the maneuver regulator and the recovery controller.

    Parameters
    ----------
    vehicle : VehicleParams
        Design model and rotor limit.
    params : SupervisorParams
    regulator_factory : callable
        ``(plan, rotor_lag) -> regulator`` (the core's ManeuverRegulator, leading by the flight's
        rotor lag in effect) with ``reset(x, s_guess)``, ``step(x)`` -> ``s, w, u, rotor_forces_n, ...``.
    envelope : EnvelopeParams, optional
        The bounds (the controller file's ``envelope:`` section); default: the defaults.
    link_health : callable, optional
        ``() -> (delay_s, jitter_s)`` or None while unknown; the health gate refuses a
        maneuver over a link worse than the envelope allows. Default: the supervisor's own
        TIMESYNC measurement (:mod:`mavreg.daemon.vehicle.timesync`).
    forecaster : Forecaster, optional
        Predicts each sample across the sample-to-actuation delay and records every command
        sent (:mod:`mavreg.control.estimation.forecast`). Default: no prediction.
    fixed_delay_s : float, optional
        A configured sample-to-actuation delay that overrides the measured one.

    The parts (:class:`~mavreg.daemon.flight.context.FlightParts`, :attr:`parts`) are also declared
    attributes of the same names (``sup.forecaster``, ``sup.monitor``, ...: one each, below); the
    flight's state is :attr:`ctx` (:class:`~mavreg.daemon.flight.context.FlightContext`).
    """

    parts: FlightParts
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
    reboots: RebootDetector

    def __init__(self, vehicle: VehicleParams, params: SupervisorParams, regulator_factory,
                 envelope: EnvelopeParams | None = None,
                 link_health: Callable[[], tuple[float, float] | None] | None = None,
                 forecaster: Forecaster | None = None, fixed_delay_s: float | None = None):
        parts = FlightParts.build(vehicle, params, regulator_factory, envelope, link_health, forecaster,
                                  fixed_delay_s)
        check_output(params.excitation, parts.output.kind)
        self.parts = parts
        self.vehicle, self.params, self.envelope = parts.vehicle, parts.params, parts.envelope
        self.regulator_factory, self.timesync, self.forecaster = parts.regulator_factory, parts.timesync, parts.forecaster
        self.hover, self.recovery, self.monitor = parts.hover, parts.recovery, parts.monitor
        self.assembler, self.output, self.delay, self.gate = parts.assembler, parts.output, parts.delay, parts.gate
        self.autopilot, self.counters, self.ids, self.reboots = parts.autopilot, parts.counters, parts.ids, parts.reboots
        self.flight = Flight(FlightContext(), parts)
        self.safety = SafetyPolicy(self.flight)
        self.handlers = make_handlers(self.flight, self.safety)
        self.inbox = Inbox(self.flight, self.safety)

    # ----------------------------------------------------------------- the flight's state
    @property
    def ctx(self) -> FlightContext:
        """The flight's state (a new one after the vehicle rebooted on the ground)."""
        return self.flight.ctx

    @property
    def phase(self) -> Phase:
        return self.ctx.phase

    @property
    def reason(self) -> str:
        return self.ctx.reason

    @property
    def failure(self) -> Outcome | None:
        """The first bound violated and every action taken since (None: the flight is clean)."""
        return self.ctx.failure

    @property
    def last_sample(self) -> StateSample | None:
        return self.ctx.heard.last_sample

    @property
    def vehicle_status(self) -> mm.VehicleStatus | None:
        return self.ctx.heard.status

    # ----------------------------------------------------------------- public API
    @property
    def finished(self) -> bool:
        return self.ctx.phase in (Phase.DISARMED, Phase.ABORTED)

    @property
    def succeeded(self) -> bool:
        """Flown within the envelope, landed (not hard), disarmed, nothing left pending."""
        ctx = self.ctx
        return (ctx.phase == Phase.DISARMED and ctx.failure is None and not ctx.pending
                and bool(ctx.maneuvers_done))

    @property
    def vehicle_refused(self) -> bool:
        """The flight ended before take-off because of the vehicle itself (its autopilot, its
        parameters, armed by another on the ground), with no maneuver queued: no later upload
        would fly either (:meth:`SafetyPolicy.refuse <mavreg.daemon.flight.safety.SafetyPolicy.refuse>`)."""
        f = self.ctx.failure
        return f is not None and f.phase == Phase.PREFLIGHT and f.action.startswith("vehicle refused")

    @property
    def airborne(self) -> bool:
        """Rotor commands are streamed to an armed vehicle (:data:`~mavreg.daemon.flight.phases.AIRBORNE`)."""
        return self.ctx.phase in AIRBORNE

    def at_safe_point(self) -> bool:
        return self.ctx.phase in (Phase.PREFLIGHT, Phase.HOLD)

    def offer_plan(self, plan, now_s: float) -> Output:
        """Queue an accepted (already planned) maneuver; it starts at the next safe point."""
        out = Output()
        ctx = self.ctx
        if self.finished or ctx.phase == Phase.TERMINATE:
            raise ValueError(f"the flight is over ({ctx.phase}); no maneuver can be queued")
        self.flight.queue(Queued(plan, self.regulator_factory(plan, self.forecaster.rotor_lag), nominal_points(plan)))
        self.flight.event(out, "queued", f"maneuver {plan.name!r} ({plan.length_m:.2f} m) queued; "
                          f"{len(ctx.pending)} pending, starts at the next safe point")
        return out

    def request_land(self, now_s: float) -> Output:
        """Land after the current maneuver (or now, when holding); drops pending maneuvers."""
        out = Output()
        ctx = self.ctx
        ctx.landing.requested = True
        self.flight.drop_pending()
        if ctx.phase == Phase.PREFLIGHT:
            self.safety.end_on_ground(out, "land requested before take-off; nothing to fly")
            return out
        self.flight.event(out, "land_requested", "landing at the next safe point")
        return out

    def heartbeat(self) -> object:
        return mm.daemon_heartbeat(self.ctx.phase not in (Phase.ABORTED, Phase.TERMINATE, Phase.RECOVER)
                                   and not self.ctx.recovery.landing)

    def status(self) -> dict:
        """The flight's status (:func:`mavreg.daemon.flight.status.supervisor_status`)."""
        return supervisor_status(self.ctx, self.counters, self.assembler.counters, self.monitor.peaks)

    def handle(self, msg, now_s: float) -> Output:
        """Process one decoded message from the link (``now_s``: the injected wall clock)."""
        return self.handle_many((msg,), now_s)

    def handle_many(self, msgs, now_s: float) -> Output:
        """A read's messages in order, as :meth:`handle`; but a sample with state parts after it
        waits for them, and one a newer sample supersedes is only checked (gap policy, envelope)
        and counted (``counters.superseded``): a loop that fell behind acts once on the state
        now. Lockstep (the vehicle waits for each answer): every sample answered at once."""
        out = Output()
        self.ctx.now_wall_s = now_s
        later = -1 if self.params.lockstep else max(
            (i for i, m in enumerate(msgs) if m.get_type() in STATE_PARTS), default=-1)
        held, was_over = None, self.finished
        for i, msg in enumerate(msgs):
            if (sample := self.inbox.take(msg, now_s, out)) is not None:
                if held is not None:
                    self._on_sample(held, now_s, out, answer=False)
                    self.counters.superseded += 1
                held = sample if i < later else None
                if held is None:
                    self._on_sample(sample, now_s, out)
            if self.finished and not was_over:     # the flight ended: the rest is the next one's
                out.taken = i + 1
                break
        if held is not None:                       # the parts after it completed nothing newer
            self._on_sample(held, now_s, out)
        return out

    def tick(self, now_s: float) -> Output:
        """Periodic check, called every ``tick_stall_s / 2`` or more often: link loss,
        forced-disarm retries (``now_s``: the injected wall clock)."""
        out = Output()
        ctx = self.ctx
        ctx.now_wall_s = now_s
        if self.finished:
            return out
        # A tick that comes late means this process was stalled (not the link): samples may
        # be waiting unread, so gaps are judged only by ticks of a running loop.
        stalled = ctx.last_tick_wall_s is not None and now_s - ctx.last_tick_wall_s > self.params.tick_stall_s
        ctx.last_tick_wall_s = now_s
        if ctx.phase == Phase.TERMINATE:
            self.safety.terminate_step(now_s, out)
        elif ctx.commands.ground_end_wall_s is not None:
            self.safety.ground_disarm_timeout(now_s, out)
        elif not stalled and ctx.heard.last_sample_wall_s is not None:
            self.safety.link_lost(now_s, out)
        return out

    def fill_gap(self, now_s: float) -> Output:
        """A sample is late (real time): command from the prediction of the last one.

        Called by the I/O layer when no complete sample has come for 1.5 control periods,
        then every period while the gap lasts. The last sample is predicted across the wall
        time since it arrived plus the link delay, the phase's controller runs on that state,
        and the command goes out as the answer to the vehicle time it stands for. Beyond the
        prediction horizon (``max_prediction_s``) nothing is sent: the vehicle holds the last
        command and the gap policy judges the gap when samples resume (docs/safety.md)."""
        out = Output()
        ctx = self.ctx
        ctx.now_wall_s = now_s
        last = ctx.heard.last_sample
        if (not self.params.gap_fill or last is None or ctx.heard.last_sample_wall_s is None
                or ctx.phase not in AIRBORNE or ctx.phase == Phase.RECOVER):
            return out
        elapsed_wall_s = now_s - ctx.heard.last_sample_wall_s
        if elapsed_wall_s < 1.5 * self.forecaster.period_s:
            return out
        fc = self.flight.forecast_ahead(last, elapsed_wall_s)
        if fc is None:
            return out
        virtual = dataclasses.replace(last, time_boot_ms=last.time_boot_ms + int(round(elapsed_wall_s * 1e3)))
        rotors, record, _ = self.handlers[ctx.phase].control(virtual, fc.x, out)
        if self.finished or not np.all(np.isfinite(rotors)):
            return out
        self.counters.gap_commands += 1
        self.flight.send_rotors(rotors, now_s, out, t_s=virtual.time_s)
        out.log = record
        return out

    def _on_sample(self, sample: StateSample, now_s: float, out: Output, answer: bool = True) -> None:
        """Every complete sample: the ground phases' handler, or the airborne pipeline;
        ``answer`` False (a newer sample came in the same read): the checks only."""
        ctx = self.ctx
        prev, prev_wall_s = ctx.heard.last_sample, ctx.heard.last_sample_wall_s
        ctx.heard.last_sample = sample
        ctx.heard.last_sample_wall_s = now_s
        if self.finished or ctx.heard.status is None:
            return
        if ctx.phase not in AIRBORNE:
            if answer:
                self.handlers[ctx.phase].on_sample(sample, now_s, out)
            return
        t = sample.time_s
        if prev is not None:
            self.safety.sample_gap(t - prev.time_s, now_s - prev_wall_s, out)
        if ctx.phase in AIRBORNE:
            v = self.monitor.check_state(t, ctx.phase, ctx.s_m, sample.position_ned, sample.velocity_ned,
                                         sample.rows, sample.rates, self.forecaster.disturbance
                                         ) or self.safety.recovery_timeout(t)
            if v is not None:
                self.safety.on_violation(v, out)
        if ctx.phase in AIRBORNE and answer:
            self._control_and_send(sample, now_s, out)

    def _control_and_send(self, sample: StateSample, now_s: float, out: Output) -> None:
        """The phase's control on the predicted state, the tracking bounds, the command out."""
        ctx = self.ctx
        x = self.flight.controller_state(sample)
        phase = ctx.phase
        rotors, record, tracking = self.handlers[phase].control(sample, x, out)
        if self.finished:
            return
        if tracking is not None:
            v = self.monitor.check_tracking(sample.time_s, phase, tracking)
            if v is not None:
                self.safety.on_violation(v, out)
                if ctx.phase not in AIRBORNE:
                    return                 # motors stopped (an impact)
                if ctx.phase != phase:     # this sample is answered by the recovery controller
                    rotors, record, _ = self.handlers[ctx.phase].control(sample, x, out)
        if not np.all(np.isfinite(rotors)):
            self.safety.non_finite(np.asarray(rotors, dtype=float), out)
            return
        self.flight.send_rotors(rotors, now_s, out)
        out.log = record
