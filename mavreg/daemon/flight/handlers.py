"""One handler per flight phase, and the table of them (sans-I/O).

:data:`HANDLERS` maps every :class:`~mavreg.daemon.flight.phases.Phase` to its handler class. A
handler is built with the flight it acts on (:class:`~mavreg.daemon.flight.verbs.Flight`) and the
safety policy (:class:`~mavreg.daemon.flight.safety.SafetyPolicy`), and is one of two kinds:

- an :class:`AirborneHandler` (the phases of :data:`~mavreg.daemon.flight.phases.AIRBORNE`):
  ``control(sample, x, out)`` returns the rotor forces, the log record and the tracking
  errors the envelope monitor judges (None: none to judge) on the state ``x`` the controllers
  act on; the supervisor's per-sample pipeline does the rest (gaps, the envelope, the
  command out);
- a :class:`GroundHandler` (the others): ``on_sample(sample, now_wall_s, out)`` does all
  there is to do with a sample.

To add a phase: a member of ``Phase`` (at the end), in ``AIRBORNE`` if the daemon streams
rotor commands in it, a handler class, and its line in :data:`HANDLERS`
(docs/architecture.md, *The supervisor*). The hover phases are in
:mod:`mavreg.daemon.flight.hover_phases`.
"""
from __future__ import annotations

import math
from typing import Protocol

import numpy as np

from ...control.controllers.hover import hold_ramp
from . import flightpath as fp
from ..vehicle import messages as mm
from .verbs import Flight, angle_between, norm3
from .gate import GateVerdict, plan_outside_envelope, sampling_verdict
from .hover_phases import Hold, Land, RunIn, Takeoff
from .monitor import Tracking
from .phases import Phase
from .safety import SafetyPolicy

__all__ = ["AirborneHandler", "GroundHandler", "Preflight", "Maneuver", "Recover", "Takeover", "Terminate", "Finished",
           "HANDLERS", "make_handlers"]


class AirborneHandler(Protocol):
    def control(self, sample, x, out) -> tuple:
        """(rotor forces N, log record, tracking errors or None) of this phase on state ``x``."""


class GroundHandler(Protocol):
    def on_sample(self, sample, now_wall_s: float, out) -> None:
        """All this phase does with a complete sample."""


class _Handler:
    def __init__(self, flight: Flight, safety: SafetyPolicy):
        self.flight = flight
        self.safety = safety


class Preflight(_Handler):
    """On the ground: the idle stream; the checks before take-off; arm, OFFBOARD, take off."""

    def on_sample(self, sample, now_wall_s: float, out) -> None:
        flight, ctx, parts = self.flight, self.flight.ctx, self.flight.parts
        params = parts.params
        t = sample.time_s
        sysid, compid = parts.ids.target
        if ctx.heard.stream_start_vehicle_s is None:
            ctx.heard.stream_start_vehicle_s = t
        st = ctx.heard.status
        by_another = st.armed and not ctx.commands.arm_requested    # it may be flying: never idled, armed or disarmed
        on_ground = ctx.heard.landed_state == mm.mavlink2.MAV_LANDED_STATE_ON_GROUND
        if ctx.landing.requested:                             # the flight ends on the ground
            if not by_another:
                flight.send_rotors(np.zeros(4), now_wall_s, out)
            if st.armed and (on_ground or not by_another):
                flight.command(out, mm.arm_disarm(sysid, compid, False))
            return
        if by_another:
            self._armed_by_another(sample, out)
            return
        flight.send_rotors(np.zeros(4), now_wall_s, out)
        if not ctx.pending:
            return
        if not st.armed:
            verdict = self._checks(sample, out)
            if verdict is None:
                return                                     # the autopilot is still answering
            if not verdict.ok:                             # as the hold's gate would, before take-off
                self.safety.refuse(verdict, out, Phase.PREFLIGHT)
            elif self._link_delay_known(t, out):
                flight.command(out, mm.arm_disarm(sysid, compid, True))
                ctx.commands.arm_requested = True
        elif not st.offboard:
            if t - ctx.heard.stream_start_vehicle_s >= params.offboard_stream_min_s:
                flight.command(out, parts.autopilot.set_offboard_mode())
        else:
            verdict = parts.gate.link_verdict(flight.gate_margin(ctx.pending[0].plan))
            if verdict is not None:
                self.safety.refuse(verdict, out, Phase.PREFLIGHT)
                return
            self._start_takeoff(sample, out)

    def _armed_by_another(self, sample, out) -> None:
        """The vehicle is armed and this daemon did not arm it (a restart after a crash, a pilot's
        take-off): airborne by its landed state (EXTENDED_SYS_STATE), or with none heard within
        ``takeover_landed_state_wait_s``, by its height over the estimate's origin, it is taken
        over (:class:`Takeover`); armed on the ground, it is refused (and disarmed only where its
        autopilot says it is on the ground: :meth:`~mavreg.daemon.flight.safety.SafetyPolicy.end_on_ground`)."""
        flight, ctx, parts = self.flight, self.flight.ctx, self.flight.parts
        params = parts.params
        waited = sample.time_s - ctx.heard.stream_start_vehicle_s
        height_m = ctx.ground_z_m - float(sample.x[2])
        if ctx.heard.landed_state is not None:
            airborne = ctx.heard.landed_state not in (mm.mavlink2.MAV_LANDED_STATE_ON_GROUND,
                                                 mm.mavlink2.MAV_LANDED_STATE_UNDEFINED)
        elif waited >= params.takeover_landed_state_wait_s:
            airborne = height_m > params.touchdown_band_m
        else:
            return                                         # its landed state may be on its way
        if not airborne:
            self.safety.refuse(GateVerdict(
                False, "armed_by_another", height_m, params.touchdown_band_m, "m",
                "the vehicle is armed on the ground and mavreg did not arm it: mavreg takes off only "
                "a vehicle it armed itself; disarm it and start again"), out, Phase.PREFLIGHT)
            return
        if not parts.delay.known and waited < params.timesync_wait_s:
            return                                         # the link delay the prediction covers
        if params.airborne == "land":
            ctx.landing.requested = True                      # serve lands it too
            if ctx.pending:
                dropped = flight.drop_pending()
                flight.event(out, "dropped", f"{dropped} not flown: the vehicle is taken over to land")
        p = np.round(sample.x[:3], 2).tolist()
        flight.announce(out, "takeover", mm.SEVERITY_WARNING,
                        f"vehicle found armed in the air at {p}, {height_m:.1f} m over the estimate's origin, "
                        f"mode {ctx.heard.status.mode}; taking it over to hold, then "
                        + ("fly the queued maneuver" if ctx.pending else "land"))
        flight.note_action("took over an airborne vehicle")
        parts.monitor.set_origin(np.array([sample.x[0], sample.x[1], ctx.ground_z_m], dtype=float))
        flight.set_phase(out, Phase.TAKEOVER, "streaming the recovery controller's set-points before OFFBOARD")

    def _checks(self, sample, out) -> GateVerdict | None:
        """The checks before arming: the plan inside the envelope from here, gains this control
        rate can fly, then the autopilot's parameters and telemetry (None while it is still
        answering; its requests go out in ``out``)."""
        parts = self.flight.parts
        q = self.flight.ctx.pending[0]
        bad = plan_outside_envelope(q.points, sample.x[:3], parts.envelope) or sampling_verdict(q.plan, q.regulator)
        return bad if bad is not None else parts.autopilot.ready(sample.time_s, out.messages)

    def _link_delay_known(self, t: float, out) -> bool:
        """The link delay is known (TIMESYNC, or configured); with no TIMESYNC answer within
        ``timesync_wait_s`` the take-off is refused."""
        ctx, parts = self.flight.ctx, self.flight.parts
        if parts.delay.known:
            return True
        waited = t - ctx.heard.stream_start_vehicle_s
        if waited < parts.params.timesync_wait_s:
            return False                                   # TIMESYNC requests go out with the stream
        self.safety.refuse(GateVerdict(
            False, "gate_no_timesync", waited, parts.params.timesync_wait_s, "s",
            "no TIMESYNC answer from the vehicle, so the link delay the controller predicts "
            "across is unknown: set fixed_delay_s in the controller file to the vehicle's "
            "sample-to-actuation delay, or enable TIMESYNC on the vehicle"), out, Phase.PREFLIGHT)
        return False

    def _start_takeoff(self, sample, out) -> None:
        flight, ctx, params = self.flight, self.flight.ctx, self.flight.parts.params
        plan = ctx.pending[0].plan
        entry = fp.entry_of(plan, params.hover, params.run_in_m, params.entry_offset_m)
        p = sample.x[:3].copy()
        ctx.ground_z_m = float(p[2])
        flight.parts.monitor.set_origin(p)
        ramps = fp.takeoff_ramps(p, float(sample.x[5]), entry, params.spool_s, params.hover)
        flight.set_phase(out, Phase.TAKEOFF, f"take-off from z={p[2]:.2f} m to hold point "
                         f"{np.round(entry.hold_m, 3).tolist()} for {plan.name!r}")
        flight.start_ramps(ramps, sample.time_s)


class Maneuver(_Handler):
    """The maneuver regulator flies the plan; at its end, stop and hold at the exit."""

    def control(self, sample, x, out):
        flight, ctx = self.flight, self.flight.ctx
        plan, reg = ctx.active.plan, ctx.active.regulator
        r = reg.step(x, ctx.heard.forecast.rotor_forces_n, flight.parts.forecaster.disturbance)
        ctx.s_m = float(r.s)
        w = np.asarray(r.w, dtype=float)
        rotors = np.asarray(r.rotor_forces_n, dtype=float)
        record = flight.record(sample, r.s, w, r.u, rotors)
        attitude_error = (float(np.linalg.norm(w[2:5])) if plan.attitude_error == "so3"   # |Log(Rbar^T R)|
                          else angle_between(x[3:6], x[3:6] - w[2:5]))
        tracking = Tracking(float(math.hypot(w[0], w[1])), attitude_error, norm3(w, 8), ctx.s_m,
                            bool(r.in_tube))
        if r.finished and np.all(np.isfinite(rotors)):
            flight.end_maneuver(finished=True)
            self._start_exit_hold(sample, out)
        return rotors, record, tracking

    def _start_exit_hold(self, sample, out) -> None:
        p = sample.x[:3]
        v = sample.velocity_ned_m_s
        ramp = fp.stop_ramp(p, v, float(sample.x[5]), self.flight.parts.params.hover)
        self.flight.set_phase(out, Phase.HOLD, f"maneuver finished at {np.round(p, 3).tolist()}, "
                              f"{float(np.linalg.norm(v)):.2f} m/s; stopping and holding at the exit")
        self.flight.start_ramps([ramp], sample.time_s)


class Recover(_Handler):
    """The recovery controller levels, brakes, climbs and holds; settled for ``settle_s``, the
    flight lands (``fly``) or holds for an upload (``serve``). Not settled in time: the safety
    policy lands it (:meth:`~mavreg.daemon.flight.safety.SafetyPolicy.recovery_timeout`)."""

    def control(self, sample, x, out):
        flight, ctx = self.flight, self.flight.ctx
        t = sample.time_s
        rotors, record, v_ned, R = flight.recovery_step(sample, x)
        if flight.parts.recovery.settled(x[:3], v_ned, R):
            if ctx.recovery.settled_since_vehicle_s is None:
                ctx.recovery.settled_since_vehicle_s = t
            if t - ctx.recovery.settled_since_vehicle_s >= flight.parts.envelope.recovery.settle_s:
                self._recovered(sample, x, out)
        else:
            ctx.recovery.settled_since_vehicle_s = None
        return rotors, record, None

    def _recovered(self, sample, x, out) -> None:
        flight, ctx = self.flight, self.flight.ctx
        t = sample.time_s
        p = np.array(x[:3], dtype=float)
        yaw = float(x[5])
        took_s = t - ctx.phase_start_vehicle_s
        flight.note_action(f"recovered after {took_s:.1f} s")
        ctx.s_m = math.nan
        land = flight.lands_when_done() and not ctx.pending   # pending: a takeover that flies it
        flight.announce(out, "recovered", mm.SEVERITY_WARNING, f"level and holding at {np.round(p, 2).tolist()} "
                        f"after {took_s:.1f} s; {'landing' if land else 'holding'}")
        if land:
            flight.set_phase(out, Phase.LAND, f"recovered at {np.round(p, 2).tolist()}; landing")
            flight.note_action("landing")
            flight.start_landing(p, yaw, t)
        else:
            flight.set_phase(out, Phase.HOLD, f"recovered at {np.round(p, 2).tolist()}; holding, "
                             + ("then the queued maneuver" if ctx.pending else "waiting for an upload"))
            flight.note_action("holding")
            flight.start_ramps([hold_ramp(p, yaw)], t)


class Takeover(_Handler):
    """A vehicle found armed in the air: the recovery controller's set-points (level, brake,
    hold where it is) stream, restarted at every sample so that nothing integrates while the
    autopilot still flies, until the autopilot grants OFFBOARD (asked for after
    ``offboard_stream_min_s`` of them); then the recovery flies (phase recover) and, settled,
    holds for the queued maneuver or lands (:meth:`Recover._recovered`). A vehicle that
    disarms meanwhile (its own failsafe landed it) is on the ground: preflight again. The
    ground is the estimate's origin (where its estimator started, on the ground)."""

    def on_sample(self, sample, now_wall_s: float, out) -> None:
        flight, ctx, parts = self.flight, self.flight.ctx, self.flight.parts
        st = ctx.heard.status
        if not st.armed:                                   # its own failsafe landed it meanwhile
            ctx.heard.stream_start_vehicle_s = None
            if ctx.pending or not parts.params.land_when_done:
                flight.set_phase(out, Phase.PREFLIGHT, "the vehicle disarmed before the takeover: on the ground")
            else:
                flight.set_phase(out, Phase.DISARMED, "the vehicle landed and disarmed before the takeover; "
                                 "nothing to fly")
            return
        x = flight.controller_state(sample)
        parts.recovery.start(x[:3], sample.velocity_ned_m_s, sample.rotation, ctx.ground_z_m)
        rotors, record, _, _ = flight.recovery_step(sample, x)
        flight.send_rotors(rotors, now_wall_s, out)
        out.log = record
        if st.offboard:
            ctx.recovery.settled_since_vehicle_s = None
            flight.set_phase(out, Phase.RECOVER, f"took over in {st.mode}: level, brake, hold")
        elif sample.time_s - ctx.phase_start_vehicle_s >= parts.params.offboard_stream_min_s:
            flight.command(out, parts.autopilot.set_offboard_mode())


class Terminate(_Handler):
    """Motors stopped after an impact: the forced disarm repeats until confirmed; no stream."""

    def on_sample(self, sample, now_wall_s: float, out) -> None:
        self.safety.terminate_step(now_wall_s, out)


class Finished(_Handler):
    """Disarmed or aborted: nothing more is done."""

    def on_sample(self, sample, now_wall_s: float, out) -> None:
        return None


HANDLERS: dict = {
    Phase.PREFLIGHT: Preflight,
    Phase.TAKEOFF: Takeoff,
    Phase.HOLD: Hold,
    Phase.RUN_IN: RunIn,
    Phase.MANEUVER: Maneuver,
    Phase.LAND: Land,
    Phase.DISARMED: Finished,
    Phase.ABORTED: Finished,
    Phase.RECOVER: Recover,
    Phase.TERMINATE: Terminate,
    Phase.TAKEOVER: Takeover,
}
"""Phase -> its handler class (airborne phases: ``control``; the others: ``on_sample``)."""


def make_handlers(flight: Flight, safety: SafetyPolicy) -> dict:
    """One handler of each phase for this flight."""
    return {phase: cls(flight, safety) for phase, cls in HANDLERS.items()}
