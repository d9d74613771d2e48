"""The verbs every part of the supervisor uses on the flight it shares (sans-I/O).

:class:`Flight` holds the flight's state (:class:`~mavreg.daemon.flight.context.FlightContext`) and
its parts (:class:`~mavreg.daemon.flight.context.FlightParts`), and is the one place that changes
the phase, stamps an event, sends a command or a rotor command, keeps the outcome and the queue
of maneuvers (``ctx`` itself is replaced by a rebuilt one when the vehicle reboots on the ground:
read it through the flight, do not keep it). The
phase handlers (:mod:`mavreg.daemon.flight.handlers`, :mod:`mavreg.daemon.flight.hover_phases`), the
safety policy (:mod:`mavreg.daemon.flight.safety`) and the supervisor act through it.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ...control.estimation.forecast import Forecast
from ...model.rotation import rpy_to_matrix
from ...model.rotation_kernel import rpy_matrix
from . import flightpath as fp
from ..vehicle import messages as mm
from .context import FlightContext, FlightParts, Flying, Queued
from .excitation import EXCITATION_END
from .gate import MarginCheck, delay_margin_of
from .phases import FREE_FLIGHT, Event, LogRecord, Output, Phase
from .records import BoundViolation, Outcome
from .state import StateSample

__all__ = ["Flight", "smoothstep", "angle_between", "norm3", "NAN11"]

NAN11 = np.full(11, np.nan)
"""The transverse error logged outside a maneuver."""


def smoothstep(t: float) -> float:
    """C^2 blend 0 -> 1 on t in [0, 1]."""
    t = min(max(t, 0.0), 1.0)
    return t * t * t * (10.0 - 15.0 * t + 6.0 * t)


def angle_between(rpy_a, rpy_b) -> float:
    """Angle of the rotation between two attitudes given as roll, pitch, yaw (any attitude)."""
    a = rpy_matrix(float(rpy_a[0]), float(rpy_a[1]), float(rpy_a[2]))
    b = rpy_matrix(float(rpy_b[0]), float(rpy_b[1]), float(rpy_b[2]))
    c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
         + a[6] * b[6] + a[7] * b[7] + a[8] * b[8] - 1.0) / 2.0    # (trace(Ra^T Rb) - 1) / 2
    return math.acos(min(max(c, -1.0), 1.0))


def norm3(v, i: int) -> float:
    """Euclidean norm of v[i:i+3]."""
    a, b, c = float(v[i]), float(v[i + 1]), float(v[i + 2])
    return math.sqrt(a * a + b * b + c * c)


class Flight:
    """One flight's state and parts, and the verbs on them.

    Parameters
    ----------
    ctx : FlightContext
    parts : FlightParts
    """

    def __init__(self, ctx: FlightContext, parts: FlightParts):
        self.ctx = ctx
        self.parts = parts

    # ------------------------------------------------------------------ phases, events
    def event(self, out: Output, kind: str, detail: str) -> None:
        """An event stamped with the vehicle's time, the phase and the arc length."""
        ctx = self.ctx
        out.events.append(Event(ctx.vehicle_now_s, kind, ctx.phase, ctx.s_m, detail))

    def set_phase(self, out: Output, phase: Phase, detail: str) -> None:
        """Enter ``phase``: the observer, the monitor's windows and the gate follow; an event."""
        ctx, parts = self.ctx, self.parts
        ctx.phase = phase
        # The disturbance observer learns only in free flight (no ground reaction force).
        parts.forecaster.observing = phase in FREE_FLIGHT
        if ctx.heard.last_sample is not None:
            ctx.phase_start_vehicle_s = ctx.heard.last_sample.time_s
        parts.monitor.phase_changed(phase, ctx.phase_start_vehicle_s)
        if phase == Phase.HOLD:
            parts.gate.reset()
            ctx.gate_wait_start_vehicle_s = None
        ctx.excitation.rate_step = None             # an excitation never outlives its hold
        if ctx.excitation.start_vehicle_s is not None and ctx.excitation.end_vehicle_s is None:
            ctx.excitation.end_vehicle_s = ctx.vehicle_now_s
            self.announce(out, "excitation", mm.SEVERITY_INFO, f"{EXCITATION_END} cut short: {phase}")
        if phase == Phase.ABORTED and not ctx.reason:
            ctx.reason = detail
        self.event(out, "phase", detail)
        # ... and in the autopilot's own log: PX4 writes a STATUSTEXT of its own system into its
        # .ulg, ArduPilot into its dataflash log (and either shows it to a ground station).
        self._statustext(out, "phase", mm.SEVERITY_INFO, f"{phase}: {detail}")

    def announce(self, out: Output, kind: str, severity: int, text: str) -> None:
        """An event, and the same words in a STATUSTEXT to the vehicle (and the .tlog)."""
        self.event(out, kind, text)
        self._statustext(out, kind, severity, text)

    def _statustext(self, out: Output, kind: str, severity: int, text: str) -> None:
        for msg in mm.statustext(severity, f"mavreg {kind}: {text}", self._statustext_id()):
            out.messages.append(msg)
            self.parts.counters.statustexts += 1

    def _statustext_id(self) -> int:
        self.ctx.statustext_id = self.ctx.statustext_id % 65535 + 1
        return self.ctx.statustext_id

    # ------------------------------------------------------------------ the maneuvers
    def queue(self, queued: Queued) -> None:
        """A maneuver accepted: flown at the next safe point, after those queued before it."""
        self.ctx.pending.append(queued)

    def drop_pending(self) -> list[str]:
        """The queued maneuvers dropped, not flown: their names."""
        names = [q.plan.name for q in self.ctx.pending]
        self.ctx.pending.clear()
        return names

    def start_next(self) -> Flying:
        """The first queued maneuver becomes the one flown (run-in, then maneuver)."""
        q = self.ctx.pending.pop(0)
        self.ctx.active = Flying(q.plan, q.regulator)
        return self.ctx.active

    def end_maneuver(self, finished: bool = False) -> None:
        """No maneuver is flown any more (``finished``: the one flown reached its end)."""
        ctx = self.ctx
        if finished and ctx.active is not None:
            ctx.maneuvers_done.append(ctx.active.plan.name)
        ctx.active = None

    # ------------------------------------------------------------------ outcome
    def fail(self, violation: BoundViolation) -> None:
        """Keep the first violation of the flight as its outcome (later ones only add actions)."""
        if self.ctx.failure is None:
            self.ctx.failure = Outcome.of(violation)

    def note_action(self, action: str) -> None:
        """A safety action taken: the outcome lists it."""
        ctx = self.ctx
        ctx.actions.append(action)
        if ctx.failure is not None:
            ctx.failure = replace(ctx.failure, action=", then ".join(ctx.actions))

    def lands_when_done(self) -> bool:
        """Whether a hold with nothing to fly ends in a landing (``fly``, or a land request)."""
        return self.parts.params.land_when_done or self.ctx.landing.requested

    # ------------------------------------------------------------------ messages out
    def command(self, out: Output, msg, at_once: bool = False) -> None:
        """Send a command, at most once per ``command_retry_s`` of vehicle time (retries), or
        ``at_once`` (a new request: its retries are counted from now). Before the vehicle's
        first sample (no vehicle time) it is not too soon."""
        ctx = self.ctx
        t, last = ctx.vehicle_now_s, ctx.commands.last_command_vehicle_s
        too_soon = last <= t < last + self.parts.params.command_retry_s    # False with a NaN
        if at_once or not too_soon:
            out.messages.append(msg)
            ctx.commands.last_command_vehicle_s = t
            self.parts.counters.commands_sent += 1

    def send_rotors(self, rotor_forces_n: np.ndarray, now_wall_s: float, out: Output,
                    t_s: float | None = None) -> None:
        """The only way a rotor command leaves: recorded by the monitor and the forecaster
        (divided by the thrust-scale calibration, clipped), sent; then a TIMESYNC request
        when one is due, so that it travels as this command does. ``t_s``: the vehicle time
        a gap-filling command stands for (default: the last sample's)."""
        ctx, parts = self.ctx, self.parts
        if t_s is not None:
            t = t_s
        else:
            t = ctx.heard.last_sample.time_s if ctx.heard.last_sample is not None else 0.0
        parts.monitor.record_command(t, rotor_forces_n)
        cmd = parts.forecaster.command(t, rotor_forces_n)
        x = ctx.heard.forecast.x if ctx.heard.forecast is not None else (
            None if ctx.heard.last_sample is None else ctx.heard.last_sample.x)
        excite = ctx.excitation.rate_step if ctx.phase == Phase.HOLD else None
        out.messages.append(parts.output.message(now_wall_s, t, cmd, x, excite))
        parts.counters.actuator_sent += 1
        if parts.timesync.due(t):
            out.messages.append(mm.timesync_request(parts.timesync.request(int(now_wall_s * 1e9), t)))

    # ------------------------------------------------------------------ control
    def controller_state(self, sample: StateSample) -> np.ndarray:
        """The state every controller acts on: the sample predicted to the instant the answer
        takes over (:class:`~mavreg.control.estimation.forecast.Forecaster`; the sample itself when
        prediction is off)."""
        parts = self.parts
        self.ctx.heard.forecast = parts.forecaster.update(sample.time_s, sample.x, sample.rotation,
                                                    parts.delay.total_s())
        return self.ctx.heard.forecast.x

    def forecast_ahead(self, last: StateSample, elapsed_wall_s: float) -> Forecast | None:
        """The last sample predicted ``elapsed_wall_s`` later plus the delay (a gap filled): kept
        as the state the controllers act on; None beyond the prediction's horizon (kept as it was)."""
        parts = self.parts
        fc = parts.forecaster.ahead(last.time_s, last.x, last.rotation, elapsed_wall_s, parts.delay.total_s())
        if fc is not None:
            self.ctx.heard.forecast = fc
        return fc

    def record(self, sample: StateSample, s, w, u, rotors) -> LogRecord:
        """The log keeps the measured state (the controllers may act on a prediction of it)."""
        est = self.parts.forecaster.disturbance
        dist = (math.nan,) * 6 if est is None else (*est.drag_n_s_per_m, *est.force_ned_n, est.thrust_scale)
        return LogRecord(sample.time_s, self.ctx.phase, s, np.asarray(w, float), np.asarray(u, float),
                         np.asarray(rotors, float), np.array(sample.x, dtype=float), dist)

    def start_ramps(self, ramps, t_vehicle_s: float) -> None:
        """The hover references to fly from vehicle time ``t_vehicle_s``, in order."""
        self.ctx.ramps = list(ramps)
        self.ctx.ramp_start_vehicle_s = t_vehicle_s

    def start_landing(self, position_m, yaw_rad: float, t_vehicle_s: float) -> None:
        """The landing ramp from ``position_m`` down to the take-off altitude."""
        p = self.parts.params
        self.start_ramps([fp.land_ramp(position_m, yaw_rad, self.ctx.ground_z_m, p.land_slow_altitude_m,
                                       p.land_speed_m_s, p.hover)], t_vehicle_s)

    def hover_step(self, sample: StateSample, x):
        """(hover output, last ramp finished) of the hover LQR on its current ramp."""
        ctx = self.ctx
        t = sample.time_s - ctx.ramp_start_vehicle_s
        while len(ctx.ramps) > 1 and ctx.ramps[0].finished(t):
            ctx.ramp_start_vehicle_s += ctx.ramps[0].duration_s
            t -= ctx.ramps[0].duration_s
            ctx.ramps.pop(0)
        ramp = ctx.ramps[0]
        return (self.parts.hover.step(x, ramp, t, self.parts.forecaster.disturbance),
                len(ctx.ramps) == 1 and ramp.finished(t))

    def recovery_step(self, sample: StateSample, x):
        """(rotor forces, log record, NED velocity, R) of the recovery controller on state ``x``."""
        R = rpy_to_matrix(*x[3:6])
        v_ned = R @ x[6:9]
        o = self.parts.recovery.step(sample.time_s, x[:3], v_ned, R, x[9:12])
        u = np.concatenate([[o.thrust_n], o.torque_n_m])
        return o.rotor_forces_n, self.record(sample, math.nan, NAN11, u, o.rotor_forces_n), v_ned, R

    def gate_margin(self, plan) -> MarginCheck | None:
        """The delay margin the gate holds the link to (:meth:`HealthGate.link_verdict`), with the
        link delay the prediction covers; None: the plan has no margins."""
        margin = delay_margin_of(plan)
        if margin is None:
            return None
        forecaster, delay = self.parts.forecaster, self.parts.delay
        covered = None
        if forecaster.predict:
            cap = forecaster.predictor.max_horizon_s
            covered = min(delay.total_s(), cap) - delay.vehicle_s
        return MarginCheck(*margin, covered, forecaster.period_s)
