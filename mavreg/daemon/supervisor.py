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

Every complete sample goes through :meth:`Supervisor._on_sample`: gap policy, the
envelope monitor on the telemetry (:mod:`mavreg.daemon.monitor`), the phase's control on
the state from :meth:`Supervisor._controller_state` (the one place a state predictor can
be slotted in), the monitor on the controller's errors, and the command out through
:meth:`Supervisor._send_rotors` (the one place every rotor command leaves). The phases are
in :mod:`mavreg.daemon.flight`, the safety actions in :mod:`mavreg.daemon.safety`,
the vocabulary in :mod:`mavreg.daemon.phases`; docs/safety.md states the envelope.
"""
from __future__ import annotations

import collections
import dataclasses
import math
from typing import Callable

import numpy as np

from ..config.defaults import CONTROL_RATE_HZ
from ..config.envelope import EnvelopeParams
from ..config.vehicle import VehicleParams
from ..control.forecast import Forecaster
from ..control.hover import HoverController
from ..control.recovery import RecoveryController
from . import messages as mm
from .flight import FlightPhases
from .gate import HealthGate, nominal_points
from .monitor import EnvelopeMonitor
from .output import command_output
from .delays import ActuationDelay
from .preflight import AutopilotSetup
from .phases import (AIRBORNE, PHASE_CODES, Counters, Event, Failure, LogRecord, Output, Phase,
                     SupervisorParams)
from .safety import SafetyActions
from .state import StateAssembler, StateSample
from .timesync import TimesyncEstimator

__all__ = ["Phase", "SupervisorParams", "Event", "LogRecord", "Output", "Supervisor", "PHASE_CODES",
           "Failure"]


class Supervisor(FlightPhases, SafetyActions):
    """Flight phases around a hover LQR, the maneuver regulator and the recovery controller.

    Parameters
    ----------
    vehicle : VehicleParams
        Design model and rotor limit.
    params : SupervisorParams
    regulator_factory : callable
        ``plan -> regulator`` with ``reset(x, s_guess)`` and ``step(x)`` returning an object
        with ``s, w, u, rotor_forces_n, in_tube, finished`` (the core's ManeuverRegulator).
    envelope : EnvelopeParams, optional
        The bounds (the controller file's ``envelope:`` section); default: the defaults.
    link_health : callable, optional
        ``() -> (delay_s, jitter_s)`` or None while unknown; the health gate refuses a
        maneuver over a link worse than the envelope allows. Default: the supervisor's own
        TIMESYNC measurement (:mod:`mavreg.daemon.timesync`).
    forecaster : Forecaster, optional
        Predicts each sample across the sample-to-actuation delay and records every command
        sent (:mod:`mavreg.control.forecast`). Default: no prediction.
    fixed_delay_s : float, optional
        A configured sample-to-actuation delay that overrides the measured one.
    """

    def __init__(self, vehicle: VehicleParams, params: SupervisorParams, regulator_factory,
                 envelope: EnvelopeParams | None = None,
                 link_health: Callable[[], tuple[float, float] | None] | None = None,
                 forecaster: Forecaster | None = None, fixed_delay_s: float | None = None):
        self.vehicle = vehicle
        self.params = params
        self.timesync = TimesyncEstimator()
        self.forecaster = forecaster if forecaster is not None else Forecaster(vehicle, 1.0 / CONTROL_RATE_HZ, predict=False)
        self._forecast = None
        self.envelope = envelope if envelope is not None else EnvelopeParams()
        self.hover = HoverController(vehicle, params.hover)
        self.recovery = RecoveryController(vehicle, self.envelope.recovery)
        self.monitor = EnvelopeMonitor(self.envelope, vehicle.mass_kg, vehicle.max_rotor_thrust_n)
        self.assembler = StateAssembler(params.euler_pitch_limit_rad)
        self.output = command_output(vehicle, params.vehicle_system_id, params.vehicle_component_id)
        self.delay = ActuationDelay(self.timesync, vehicle, self.output.kind, fixed_delay_s)
        self.gate = HealthGate(self.envelope, vehicle.mass_kg, vehicle.max_rotor_thrust_n,
                               link_health if link_health is not None else self.delay.measured_link)
        self.autopilot = AutopilotSetup(params.vehicle_system_id, params.vehicle_component_id,
                                        params.telemetry_rate_hz, params.parameter_timeout_s)
        self.regulator_factory = regulator_factory
        self.counters = Counters()
        self.phase = Phase.PREFLIGHT
        self.reason = ""
        self.failure: Failure | None = None
        self.vehicle_status: mm.VehicleStatus | None = None
        self.last_sample: StateSample | None = None
        self._now_s = 0.0
        self._last_sample_now: float | None = None
        self._stream_start_t: float | None = None
        self._last_cmd_t = -math.inf
        self._last_tick_now: float | None = None
        self._pending: list = []        # (plan, regulator, nominal points) not yet flown
        self._active = None             # (plan, regulator) in run_in / maneuver
        self._maneuvers_done: list[str] = []
        self._ramps = []
        self._ramp_t0 = 0.0
        self._phase_t0 = 0.0
        self._ground_z = 0.0
        self._spool_down_t0: float | None = None
        self._land_mode_requested = False
        self._descent: collections.deque = collections.deque()
        self._touchdown_speed: float | None = None
        self._land_requested = False
        self._s = math.nan
        self._recoveries = 0
        self._recovery_landing = False
        """The recovery controller is landing the vehicle (phase LAND)."""
        self._noted_bounds: set = set()
        self._settled_since: float | None = None
        self._actions: list[str] = []
        self._gate_wait_t0: float | None = None
        self._gate_last = None
        self._terminate_t0 = 0.0
        self._disarm_sent = -math.inf
        self._text_id = 0

    # ----------------------------------------------------------------- public API
    @property
    def finished(self) -> bool:
        return self.phase in (Phase.DISARMED, Phase.ABORTED)

    @property
    def succeeded(self) -> bool:
        """Flown within the envelope, landed (not hard), disarmed, nothing left pending."""
        return (self.phase == Phase.DISARMED and self.failure is None and not self._pending
                and bool(self._maneuvers_done))

    def at_safe_point(self) -> bool:
        return self.phase in (Phase.PREFLIGHT, Phase.HOLD)

    def offer_plan(self, plan, now_s: float) -> Output:
        """Queue an accepted (already planned) maneuver; it starts at the next safe point."""
        out = Output()
        if self.finished or self.phase == Phase.TERMINATE:
            raise ValueError(f"the flight is over ({self.phase}); no maneuver can be queued")
        self._pending.append((plan, self.regulator_factory(plan), nominal_points(plan)))
        self._event(out, "queued", f"maneuver {plan.name!r} ({plan.length_m:.2f} m) queued; "
                    f"{len(self._pending)} pending, starts at the next safe point")
        return out

    def request_land(self, now_s: float) -> Output:
        """Land after the current maneuver (or now, when holding); drops pending maneuvers."""
        out = Output()
        self._land_requested = True
        self._pending.clear()
        if self.phase == Phase.PREFLIGHT:
            armed = self.vehicle_status is not None and self.vehicle_status.armed
            if not armed:
                self._set_phase(out, Phase.DISARMED, "land requested before take-off; nothing to fly")
            else:
                self._event(out, "land_requested", "disarming on the ground")
            return out
        self._event(out, "land_requested", "landing at the next safe point")
        return out

    def heartbeat(self) -> object:
        return mm.daemon_heartbeat(self.phase not in (Phase.ABORTED, Phase.TERMINATE, Phase.RECOVER)
                                   and not self._recovery_landing)

    def status(self) -> dict:
        c = self.counters
        a = self.assembler.counters
        return {
            "phase": self.phase, "reason": self.reason, "s_m": None if math.isnan(self._s) else self._s,
            "active": None if self._active is None else self._active[0].name,
            "pending": [p.name for p, _, _ in self._pending], "done": list(self._maneuvers_done),
            "vehicle_mode": None if self.vehicle_status is None else self.vehicle_status.mode,
            "vehicle_armed": None if self.vehicle_status is None else self.vehicle_status.armed,
            "failure": None if self.failure is None else self.failure.as_dict(),
            "recoveries": self._recoveries, "touchdown_speed_m_s": self._touchdown_speed,
            "envelope_peaks": {k: dict(v) for k, v in sorted(self.monitor.peaks.items())},
            "counters": {**c.__dict__, "state_late": a.late, "state_unmatched": a.unmatched,
                         "state_euler_refused": a.euler_near_vertical, "state_non_finite": a.non_finite},
        }

    def handle(self, msg, now_s: float) -> Output:
        """Process one decoded message from the link."""
        out = Output()
        self._now_s = now_s
        if (msg.get_srcSystem() != self.params.vehicle_system_id
                or msg.get_srcComponent() != self.params.vehicle_component_id):
            self.counters.foreign_dropped += 1
            return out
        mtype = msg.get_type()
        if mtype == "HEARTBEAT":
            st = self.autopilot.heartbeat(msg, out.messages, self.last_sample is not None)
            if st is not None:
                self._on_heartbeat(st, out)
            else:
                self.counters.unsupported_heartbeats += 1
        elif mtype == "PARAM_VALUE":
            self.autopilot.param_value(msg)
        elif mtype == "COMMAND_ACK":
            self._on_ack(msg, out)
        elif mtype == "TIMESYNC":
            if msg.tc1 != 0 and not self.timesync.reply(msg.tc1, msg.ts1, int(now_s * 1e9)):
                self.counters.timesync_dropped += 1
        else:
            sample = self.assembler.add(msg)
            if sample is not None:
                self.counters.samples += 1
                self._on_sample(sample, now_s, out)
        return out

    def tick(self, now_s: float) -> Output:
        """Periodic check, called every ``tick_stall_s / 2`` or more often: link loss,
        forced-disarm retries."""
        out = Output()
        self._now_s = now_s
        if self.finished:
            return out
        # A tick that comes late means this process was stalled (not the link): samples may
        # be waiting unread, so gaps are judged only by ticks of a running loop.
        stalled = self._last_tick_now is not None and now_s - self._last_tick_now > self.params.tick_stall_s
        self._last_tick_now = now_s
        if self.phase == Phase.TERMINATE:
            self._terminate_step(now_s, out)
        elif not stalled and self._last_sample_now is not None:
            self._wall_clock_gap(now_s, out)
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
        self._now_s = now_s
        last = self.last_sample
        if (not self.params.gap_fill or last is None or self._last_sample_now is None
                or self.phase not in AIRBORNE or self.phase == Phase.RECOVER):
            return out
        elapsed = now_s - self._last_sample_now
        if elapsed < 1.5 * self.forecaster.period_s:
            return out
        fc = self.forecaster.ahead(last.time_s, last.x, last.rotation, elapsed, self.delay.total_s())
        if fc is None:
            return out
        virtual = dataclasses.replace(last, time_boot_ms=last.time_boot_ms + int(round(elapsed * 1e3)))
        self._forecast = fc
        rotors, record, _ = self._control(virtual, fc.x, out)
        if self.finished or not np.all(np.isfinite(rotors)):
            return out
        self.counters.gap_commands += 1
        self._send_rotors(rotors, now_s, out, t_s=virtual.time_s)
        out.log = record
        return out

    # ----------------------------------------------------------------- internals
    def _event(self, out: Output, kind: str, detail: str) -> None:
        t = self.last_sample.time_s if self.last_sample is not None else math.nan
        out.events.append(Event(t, kind, self.phase, self._s, detail))

    def _set_phase(self, out: Output, phase: str, detail: str) -> None:
        self.phase = phase
        # The disturbance observer learns only in free flight (no ground reaction force).
        self.forecaster.observing = phase in (Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER)
        if self.last_sample is not None:
            self._phase_t0 = self.last_sample.time_s
        self.monitor.phase_changed(phase, self._phase_t0)
        if phase == Phase.HOLD:
            self.gate.reset()
            self._gate_wait_t0 = None
        if phase == Phase.ABORTED and not self.reason:
            self.reason = detail
        self._event(out, "phase", detail)

    def _on_heartbeat(self, st: mm.VehicleStatus, out: Output) -> None:
        prev = self.vehicle_status
        self.vehicle_status = st
        if prev is None or prev.armed != st.armed or prev.mode != st.mode:
            self._event(out, "vehicle", f"vehicle {'armed' if st.armed else 'disarmed'}, mode {st.mode}")
        if self.phase == Phase.TERMINATE:
            if not st.armed:
                self._disarm_confirmed(out, "the vehicle reports disarmed")
        elif self.phase == Phase.LAND and self._spool_down_t0 is not None and not st.armed:
            self._set_phase(out, Phase.DISARMED, "touched down and disarmed")
        elif self.phase == Phase.PREFLIGHT and self._land_requested and not st.armed:
            self._set_phase(out, Phase.DISARMED, "disarmed on the ground")
        elif self.phase == Phase.LAND and self._land_mode_requested and st.mode == self.autopilot.dialect.land_mode:
            pass                           # on the ground, the autopilot's landing mode disarms
        elif self.phase in AIRBORNE and (not st.armed or not st.offboard):
            self._hand_over(out, "vehicle_mode", math.nan, math.nan, "",
                            f"vehicle left OFFBOARD control (armed={st.armed}, mode {st.mode}); "
                            "its failsafe is in charge")

    def _on_ack(self, msg, out: Output) -> None:
        self.counters.acks += 1
        accepted = msg.result == mm.mavlink2.MAV_RESULT_ACCEPTED
        if not accepted:
            self._event(out, "command_refused", f"command {msg.command} result {msg.result}")
        if (accepted and self.phase == Phase.TERMINATE
                and msg.command == mm.mavlink2.MAV_CMD_COMPONENT_ARM_DISARM):
            self._disarm_confirmed(out, "forced disarm acknowledged")

    def _command(self, out: Output, msg) -> None:
        """Send a command, at most once per ``command_retry_s`` of vehicle time (retries)."""
        t = self.last_sample.time_s
        if t - self._last_cmd_t >= self.params.command_retry_s or t < self._last_cmd_t:
            out.messages.append(msg)
            self._last_cmd_t = t
            self.counters.commands_sent += 1

    def _on_sample(self, sample: StateSample, now_s: float, out: Output) -> None:
        prev, prev_now = self.last_sample, self._last_sample_now
        self.last_sample = sample
        self._last_sample_now = now_s
        if self.vehicle_status is None and self.autopilot.unsupported is not None and self._pending:
            self._refuse(self.autopilot.ready(sample.time_s, out.messages), out, Phase.PREFLIGHT)
        if self.finished or self.vehicle_status is None:
            return
        if self.phase == Phase.TERMINATE:
            self._terminate_step(now_s, out)
            return
        if self.phase == Phase.PREFLIGHT:
            self._preflight(sample, now_s, out)
            return
        t = sample.time_s
        if prev is not None:
            self._gap(t - prev.time_s, now_s - prev_now, out)
        if self.phase in AIRBORNE:
            v = self.monitor.check_state(t, self.phase, self._s, sample.position_ned, sample.velocity_ned,
                                         sample.rows, sample.rates, self.forecaster.disturbance
                                         ) or self._recovery_timeout(t)
            if v is not None:
                self._violation(v, out)
        if self.phase not in AIRBORNE:
            return
        x = self._controller_state(sample)
        phase = self.phase
        rotors, record, tracking = self._control(sample, x, out)
        if self.finished:
            return
        if tracking is not None:
            v = self.monitor.check_tracking(t, phase, tracking)
            if v is not None:
                self._violation(v, out)
                if self.phase not in AIRBORNE:
                    return                 # motors stopped (an impact)
                if self.phase != phase:    # this sample is answered by the recovery controller
                    rotors, record, _ = self._control(sample, x, out)
        if not np.all(np.isfinite(rotors)):
            self._non_finite(np.asarray(rotors, dtype=float), out)
            return
        self._send_rotors(rotors, now_s, out)
        out.log = record

    def _controller_state(self, sample: StateSample) -> np.ndarray:
        """The state every controller acts on: the sample predicted to the instant the answer
        takes over (:class:`~mavreg.control.forecast.Forecaster`; the sample itself when
        prediction is off)."""
        self._forecast = self.forecaster.update(sample.time_s, sample.x, sample.rotation,
                                                self.delay.total_s())
        return self._forecast.x

    def _send_rotors(self, rotor_forces_n: np.ndarray, now_s: float, out: Output,
                     t_s: float | None = None) -> None:
        """The only way a rotor command leaves: recorded by the monitor and the forecaster
        (divided by the thrust-scale calibration, clipped), sent; then a TIMESYNC request
        when one is due, so that it travels as this command does."""
        if t_s is not None:
            t = t_s                    # a gap-filling command: the vehicle time it stands for
        else:
            t = self.last_sample.time_s if self.last_sample is not None else 0.0
        self.monitor.record_command(t, rotor_forces_n)
        cmd = self.forecaster.command(t, rotor_forces_n)
        x = self._forecast.x if self._forecast is not None else (
            None if self.last_sample is None else self.last_sample.x)
        out.messages.append(self.output.message(now_s, t, cmd, x))
        self.counters.actuator_sent += 1
        if self.timesync.due(t):
            out.messages.append(mm.timesync_request(self.timesync.request(int(now_s * 1e9), t)))
