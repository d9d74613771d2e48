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
(:class:`~mavreg.daemon.flight.safety.SafetyPolicy`), the vocabulary in :mod:`mavreg.daemon.flight.phases`
and the records in :mod:`mavreg.daemon.flight.records`. This module routes messages and runs the
per-sample pipeline (:meth:`Supervisor._on_sample`): gap policy, the envelope monitor on the
telemetry (:mod:`mavreg.daemon.flight.monitor`), the phase's control on the state from
:meth:`Flight.controller_state` (the one place a state predictor can be slotted in), the
monitor on the controller's errors, and the command out through :meth:`Flight.send_rotors`
(the one place every rotor command leaves). docs/safety.md states the envelope.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Callable

import numpy as np

from ...config.envelope import EnvelopeParams
from ...config.vehicle import VehicleParams
from ...control.estimation.forecast import Forecaster
from ..vehicle import messages as mm
from .context import FlightContext, FlightParts
from .status import supervisor_status
from .excitation import check_output
from .verbs import Flight
from .gate import nominal_points
from .handlers import make_handlers
from .phases import AIRBORNE, PHASE_CODES, Event, LogRecord, Output, Phase, SupervisorParams
from .reboot import STATE_PARTS, on_reboot
from .records import Outcome
from .safety import SafetyPolicy
from .state import StateSample

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

    The parts (``forecaster``, ``hover``, ``recovery``, ``monitor``, ``gate``, ``delay``,
    ``timesync``, ``assembler``, ``autopilot``, ``output``, ``counters``, ...) are attributes
    of the same names (:class:`~mavreg.daemon.flight.context.FlightParts`); the flight's state is
    :attr:`ctx` (:class:`~mavreg.daemon.flight.context.FlightContext`).
    """

    def __init__(self, vehicle: VehicleParams, params: SupervisorParams, regulator_factory,
                 envelope: EnvelopeParams | None = None,
                 link_health: Callable[[], tuple[float, float] | None] | None = None,
                 forecaster: Forecaster | None = None, fixed_delay_s: float | None = None):
        parts = FlightParts.build(vehicle, params, regulator_factory, envelope, link_health, forecaster,
                                  fixed_delay_s)
        check_output(params.excitation, parts.output.kind)
        for f in dataclasses.fields(parts):          # sup.forecaster, sup.monitor, ...: the parts
            setattr(self, f.name, getattr(parts, f.name))
        self.ctx = FlightContext()
        self.flight = Flight(self.ctx, parts)
        self.safety = SafetyPolicy(self.flight)
        self.handlers = make_handlers(self.flight, self.safety)

    # ----------------------------------------------------------------- the flight's state
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
        return self.ctx.last_sample

    @property
    def vehicle_status(self) -> mm.VehicleStatus | None:
        return self.ctx.vehicle_status

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
        ctx.pending.append((plan, self.regulator_factory(plan, self.forecaster.rotor_lag), nominal_points(plan)))
        self.flight.event(out, "queued", f"maneuver {plan.name!r} ({plan.length_m:.2f} m) queued; "
                          f"{len(ctx.pending)} pending, starts at the next safe point")
        return out

    def request_land(self, now_s: float) -> Output:
        """Land after the current maneuver (or now, when holding); drops pending maneuvers."""
        out = Output()
        ctx = self.ctx
        ctx.land_requested = True
        ctx.pending.clear()
        if ctx.phase == Phase.PREFLIGHT:
            self.safety.end_on_ground(out, "land requested before take-off; nothing to fly")
            return out
        self.flight.event(out, "land_requested", "landing at the next safe point")
        return out

    def heartbeat(self) -> object:
        return mm.daemon_heartbeat(self.ctx.phase not in (Phase.ABORTED, Phase.TERMINATE, Phase.RECOVER)
                                   and not self.ctx.recovery_landing)

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
            if (sample := self._take(msg, now_s, out)) is not None:
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

    def _take(self, msg, now_s: float, out: Output) -> StateSample | None:
        """One message: routed; the complete sample it closes, if any (not yet acted on)."""
        mtype = msg.get_type()
        if not self._vehicle_ids(msg, mtype, out):
            self.counters.foreign_dropped += 1
            return None
        if mtype in STATE_PARTS and (seen := self.reboots.part(msg, now_s)) is not None:
            on_reboot(self.flight, self.safety, seen, out)
        if mtype == "HEARTBEAT":
            self._heartbeat(msg, out)
        elif mtype == "PARAM_VALUE":
            self.autopilot.param_value(msg)
        elif mtype == "COMMAND_ACK":
            self._on_ack(msg, out)
        elif mtype == "EXTENDED_SYS_STATE":
            self.ctx.landed_state = int(msg.landed_state)
        elif mtype == "TIMESYNC":
            if msg.tc1 != 0 and not self.timesync.reply(msg.tc1, msg.ts1, int(now_s * 1e9)):
                self.counters.timesync_dropped += 1
        else:
            sample = self.assembler.add(msg)
            if sample is not None:
                self.counters.samples += 1
                return sample
        return None

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
        elif ctx.ground_end_wall_s is not None:
            self.safety.ground_disarm_timeout(now_s, out)
        elif not stalled and ctx.last_sample_wall_s is not None:
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
        last = ctx.last_sample
        if (not self.params.gap_fill or last is None or ctx.last_sample_wall_s is None
                or ctx.phase not in AIRBORNE or ctx.phase == Phase.RECOVER):
            return out
        elapsed_wall_s = now_s - ctx.last_sample_wall_s
        if elapsed_wall_s < 1.5 * self.forecaster.period_s:
            return out
        fc = self.forecaster.ahead(last.time_s, last.x, last.rotation, elapsed_wall_s, self.delay.total_s())
        if fc is None:
            return out
        virtual = dataclasses.replace(last, time_boot_ms=last.time_boot_ms + int(round(elapsed_wall_s * 1e3)))
        ctx.forecast = fc
        rotors, record, _ = self.handlers[ctx.phase].control(virtual, fc.x, out)
        if self.finished or not np.all(np.isfinite(rotors)):
            return out
        self.counters.gap_commands += 1
        self.flight.send_rotors(rotors, now_s, out, t_s=virtual.time_s)
        out.log = record
        return out

    # ----------------------------------------------------------------- messages in
    def _vehicle_ids(self, msg, mtype: str, out: Output) -> bool:
        """Whether ``msg`` is the vehicle's (:class:`~mavreg.daemon.vehicle.peers.VehicleIds`: its system
        id pinned, or fixed by its first autopilot HEARTBEAT, which is announced)."""
        ids = self.ids
        known = ids.system_id is not None
        hb = (int(msg.type), int(msg.autopilot)) if mtype == "HEARTBEAT" else None
        if not ids.take(msg.get_srcSystem(), msg.get_srcComponent(), hb):
            return False
        if not known:
            self.flight.event(out, "vehicle_id", f"vehicle system id {ids.system_id}, from its first autopilot "
                              f"HEARTBEAT (autopilot {hb[1]}); pin another with --vehicle-system-id N")
        return True

    def _heartbeat(self, msg, out: Output) -> None:
        """A vehicle HEARTBEAT: the dialect (its notice), then the vehicle's status; a vehicle
        mavreg does not fly is refused on the ground at once."""
        autopilot, ctx = self.autopilot, self.ctx
        self.reboots.heartbeat(ctx.now_wall_s)
        # the telemetry is asked for until samples stream: from the start, and on the ground when
        # they stopped (a rebooted ArduCopter sends none until asked again)
        streaming = ctx.last_sample_wall_s is not None and (
            ctx.phase in AIRBORNE or ctx.now_wall_s - ctx.last_sample_wall_s <= self.params.stale_timeout_s)
        st = autopilot.heartbeat(msg, out.messages, streaming)
        if autopilot.notice is not None:
            self.flight.announce(out, "dialect", mm.SEVERITY_WARNING, autopilot.notice)
            autopilot.notice = None
        if st is not None:
            self._on_heartbeat(st, out)
            return
        self.counters.unsupported_heartbeats += 1
        if self.ctx.phase == Phase.PREFLIGHT:
            self.safety.refuse(autopilot.refusal, out, Phase.PREFLIGHT)

    def _on_heartbeat(self, st: mm.VehicleStatus, out: Output) -> None:
        ctx = self.ctx
        prev = ctx.vehicle_status
        ctx.vehicle_status = st
        if prev is None or prev.armed != st.armed or prev.mode != st.mode:
            self.flight.event(out, "vehicle", f"vehicle {'armed' if st.armed else 'disarmed'}, mode {st.mode}")
        if ctx.phase == Phase.TERMINATE:
            if not st.armed:
                self.safety.disarm_confirmed(out, "the vehicle reports disarmed")
        elif ctx.phase == Phase.LAND and ctx.spool_down_start_vehicle_s is not None and not st.armed:
            self.flight.set_phase(out, Phase.DISARMED, "touched down and disarmed")
        elif ctx.phase == Phase.PREFLIGHT and ctx.land_requested and not st.armed:
            self.flight.set_phase(out, Phase.DISARMED, "disarmed on the ground")
        elif (ctx.phase == Phase.LAND and ctx.land_mode_requested
              and st.mode == self.autopilot.dialect.land_mode):
            pass                           # on the ground, the autopilot's landing mode disarms
        elif ctx.phase in AIRBORNE and (not st.armed or not st.offboard):
            self.safety.hand_over(out, "vehicle_mode", math.nan, math.nan, "",
                                  f"vehicle left OFFBOARD control (armed={st.armed}, mode {st.mode}); "
                                  "its failsafe is in charge")

    def _on_ack(self, msg, out: Output) -> None:
        self.counters.acks += 1
        accepted = msg.result == mm.mavlink2.MAV_RESULT_ACCEPTED
        if not accepted:
            self.flight.event(out, "command_refused", f"command {msg.command} result {msg.result}")
        if (accepted and self.ctx.phase == Phase.TERMINATE
                and msg.command == mm.mavlink2.MAV_CMD_COMPONENT_ARM_DISARM):
            self.safety.disarm_confirmed(out, "forced disarm acknowledged")

    def _on_sample(self, sample: StateSample, now_s: float, out: Output, answer: bool = True) -> None:
        """Every complete sample: the ground phases' handler, or the airborne pipeline;
        ``answer`` False (a newer sample came in the same read): the checks only."""
        ctx = self.ctx
        prev, prev_wall_s = ctx.last_sample, ctx.last_sample_wall_s
        ctx.last_sample = sample
        ctx.last_sample_wall_s = now_s
        if self.finished or ctx.vehicle_status is None:
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
