"""The supervisor's safety policy: the actions, in order of severity, and the gap policy.

:class:`SafetyPolicy` decides what a violated bound (a
:class:`~mavreg.daemon.flight.records.BoundViolation`) does to the flight it shares with the phase
handlers (:class:`~mavreg.daemon.flight.verbs.Flight`): recover, land with the recovery controller,
and, after an impact only, stop the motors.

The rule: **the motors are never stopped in the air because a bound fired.** A safety
action must not be worse than the fault it answers, and a vehicle whose motors stop falls.

- **Recover** (:meth:`SafetyPolicy._recover`): a bound of the envelope is violated in
  flight. The maneuver (or hover) control is left for the recovery controller
  (:mod:`mavreg.control.controllers.recovery`): level, brake, climb to a safe altitude, hold; then land
  (``fly``) or hold and wait for an upload (``serve``). Pending maneuvers are dropped. A
  recovery is judged over ``recovery.timeout_s``, not by one sample: a bound that fires
  while it flies is announced once and the recovery goes on.
- **Land with the recovery controller** (:meth:`SafetyPolicy._recovery_land`): a recovery
  that has not settled within its time, a violation after ``max_recoveries``, or a
  violation near the ground (within ``impact_altitude_m``). The recovery controller,
  which holds any attitude, descends at the landing speed; at touchdown the rotors spool
  down and the vehicle is disarmed, as in a normal landing. Bounds that fire on the way
  down are announced once; the landing goes on.
- **Stop the motors** (:meth:`SafetyPolicy._terminate`): only after an impact, i.e. ground
  contact confirmed by the telemetry (within ``impact_altitude_m`` of the take-off altitude
  and descending or moving faster than the impact bounds, an acceleration spike there, or
  thrust contradicted there). COMMAND_LONG ARM_DISARM param1 = 0, param2 = 21196 (forced),
  repeated every ``disarm_retry_s`` until acknowledged or reported disarmed; the actuator
  stream stops for good. No thrust is ever commanded again.
- **Hand over** (:meth:`SafetyPolicy.hand_over`): the link is lost (no sample for
  ``stale_timeout_s``), the controller output is not finite, or the vehicle left OFFBOARD:
  the stream stops for good and the vehicle's failsafe flies.
- **Refuse** (:meth:`SafetyPolicy.refuse`): the health gate does not pass within its time:
  the maneuver is not flown; hold, then land (``fly``) or keep holding (``serve``). A refusal
  before take-off (the vehicle's autopilot or dialect, its parameters, the plan outside the
  envelope, no link delay, a link too slow) ends the flight on the ground
  (:meth:`SafetyPolicy.end_on_ground`): at once when the vehicle is disarmed, after its
  disarm (or ``ground_disarm_timeout_s``) when it is armed; ``fly`` then exits 1 with the
  cause in one line.

Every action is an :class:`~mavreg.daemon.flight.phases.Event`, a log line (the app prints events)
and a STATUSTEXT to the vehicle (CRITICAL for recover / land / stop / hand over, WARNING for
a refusal or a hard landing); the first bound violated is kept as the flight's
:class:`~mavreg.daemon.flight.records.Outcome`, with every action taken after it.

Gaps (docs/safety.md): a complete sample that follows the previous one by more than
``maneuver_gap_s`` of both vehicle time and injected clock starts a recovery in run-in or
maneuver, and is counted (and tolerated) elsewhere; a running tick that has seen no sample
for ``stale_timeout_s`` (injected clock) hands over, in every armed phase.
"""
from __future__ import annotations

import math

import numpy as np

from ..vehicle import messages as mm
from .verbs import Flight
from .phases import AIRBORNE, Phase
from .records import BoundViolation

__all__ = ["SafetyPolicy"]


class SafetyPolicy:
    """The bound trips and the actions they take (see the module docstring).

    Parameters
    ----------
    flight : Flight
        The flight's state, parts and verbs, shared with the phase handlers.
    """

    def __init__(self, flight: Flight):
        self.flight = flight

    # ------------------------------------------------------------------ violations
    def on_violation(self, v: BoundViolation, out) -> None:
        """Act on a violated bound: recover, land with the recovery controller, or (after an
        impact only) stop the motors."""
        flight, ctx, parts = self.flight, self.flight.ctx, self.flight.parts
        flight.fail(v)
        sample = ctx.heard.last_sample
        at_ground = sample is not None and parts.monitor.altitude_m(sample.x[:3]) <= parts.envelope.impact_altitude_m
        recovery = parts.envelope.recovery
        if v.impact:
            self._terminate(out, f"impact: {v.describe()}")
        elif ctx.recovery.landing:
            self._note_bound(out, v, "landing on")
        elif ctx.phase == Phase.RECOVER and v.bound == "recovery_timeout":
            self._recovery_land(out, f"recovery not settled: {v.describe()}")
        elif ctx.phase == Phase.RECOVER:
            self._note_bound(out, v, f"recovery goes on, judged over {recovery.timeout_s:g} s")
        elif at_ground:
            self._recovery_land(out, f"at the ground: {v.describe()}")
        elif ctx.recovery.count >= recovery.max_recoveries:
            self._recovery_land(out, f"recovery {ctx.recovery.count + 1} not allowed: {v.describe()}")
        else:
            self._recover(v, out)

    def recovery_timeout(self, t_s: float) -> BoundViolation | None:
        """The violation of a recovery that has not settled within its time limit, or None."""
        ctx = self.flight.ctx
        limit = self.flight.parts.envelope.recovery.timeout_s
        if ctx.phase == Phase.RECOVER and t_s - ctx.phase_start_vehicle_s > limit:
            return BoundViolation("recovery_timeout", Phase.RECOVER, t_s, math.nan,
                                  t_s - ctx.phase_start_vehicle_s, limit, "s",
                                  "not level, slow and at the safe altitude in time")
        return None

    def _note_bound(self, out, v: BoundViolation, then: str) -> None:
        """A bound that fired while the recovery controller flies: announced once per bound."""
        ctx = self.flight.ctx
        if v.bound in ctx.recovery.noted_bounds:
            return
        ctx.recovery.noted_bounds.add(v.bound)
        self.flight.announce(out, "bound", mm.SEVERITY_WARNING, f"{v.describe()}; {then}")

    def _to_recovery_controller(self, start: bool) -> list:
        """The recovery controller takes over (``start``: from the last sample): the maneuver
        and pending ones are dropped; their names are returned."""
        ctx = self.flight.ctx
        if start:
            s = ctx.heard.last_sample
            self.flight.parts.recovery.start(s.x[:3], s.velocity_ned_m_s, s.rotation, ctx.ground_z_m)
        dropped = self.flight.drop_pending()
        self.flight.end_maneuver()
        ctx.recovery.noted_bounds = set()
        ctx.s_m = math.nan
        return dropped

    def _recover(self, v: BoundViolation, out) -> None:
        flight, ctx = self.flight, self.flight.ctx
        ctx.recovery.count += 1
        dropped = self._to_recovery_controller(start=True)
        ctx.recovery.settled_since_vehicle_s = None
        safe = flight.parts.envelope.recovery.safe_altitude_m
        flight.announce(out, "recover", mm.SEVERITY_CRITICAL, f"{v.describe()}; recovering: level, brake, "
                        f"climb to {safe:g} m, hold" + (f" (dropped {dropped})" if dropped else ""))
        flight.note_action("recovery")
        flight.set_phase(out, Phase.RECOVER, f"recovery {ctx.recovery.count} begins")

    def _recovery_land(self, out, why: str) -> None:
        """Land where the vehicle is with the recovery controller (any attitude), at the
        landing speed; the landing's touchdown, spool-down and disarm follow."""
        flight, ctx = self.flight, self.flight.ctx
        speed = flight.parts.params.land_speed_m_s
        self._to_recovery_controller(start=ctx.phase != Phase.RECOVER)
        flight.parts.recovery.land(ctx.ground_z_m, speed)
        ctx.recovery.landing = True
        flight.announce(out, "recovery_land", mm.SEVERITY_CRITICAL,
                        f"{why}; landing with the recovery controller at {speed:g} m/s")
        flight.note_action("landing (recovery controller)")
        flight.set_phase(out, Phase.LAND, "landing where it is with the recovery controller")

    # ------------------------------------------------------------------ motors stopped, hand over
    def _terminate(self, out, why: str) -> None:
        """Stop the motors: forced disarm until confirmed, no actuator stream ever again.
        Only after an impact (ground contact), never in the air."""
        flight, ctx = self.flight, self.flight.ctx
        flight.announce(out, "motors_stopped", mm.SEVERITY_CRITICAL, f"{why}; forced disarm")
        flight.note_action("motors stopped (forced disarm)")
        flight.end_maneuver()
        flight.drop_pending()
        flight.set_phase(out, Phase.TERMINATE, "forced disarm, repeated until the vehicle confirms it; "
                         "no rotor command is sent any more")
        ctx.commands.terminate_start_wall_s = ctx.now_wall_s
        ctx.commands.disarm_sent_wall_s = -math.inf
        self.terminate_step(ctx.now_wall_s, out)

    def terminate_step(self, now_wall_s: float, out) -> None:
        """Repeat the forced disarm; give up (stream stopped anyway) after ``terminate_timeout_s``."""
        flight, ctx, params = self.flight, self.flight.ctx, self.flight.parts.params
        if now_wall_s - ctx.commands.terminate_start_wall_s > params.terminate_timeout_s:
            flight.note_action("disarm not confirmed")
            flight.set_phase(out, Phase.ABORTED, f"forced disarm not confirmed within "
                             f"{params.terminate_timeout_s:g} s; the vehicle's failsafe is in charge")
            return
        if now_wall_s - ctx.commands.disarm_sent_wall_s >= params.disarm_retry_s:
            out.messages.append(mm.force_disarm(*flight.parts.ids.target))
            flight.parts.counters.commands_sent += 1
            ctx.commands.disarm_sent_wall_s = now_wall_s

    def disarm_confirmed(self, out, how: str) -> None:
        self.flight.note_action(f"disarmed ({how})")
        self.flight.set_phase(out, Phase.DISARMED, f"motors stopped: {how}")

    def hand_over(self, out, bound: str, value: float, limit: float, unit: str, detail: str) -> None:
        """Stop the stream for good: the vehicle's failsafe flies."""
        flight, ctx = self.flight, self.flight.ctx
        flight.fail(BoundViolation(bound, ctx.phase, ctx.vehicle_now_s, ctx.s_m, value, limit, unit, detail))
        ctx.reason = detail
        flight.announce(out, "hand_over", mm.SEVERITY_CRITICAL, f"{detail}; command stream stopped, "
                        "the vehicle's failsafe is in charge")
        flight.note_action("command stream stopped (vehicle failsafe)")
        flight.set_phase(out, Phase.ABORTED, detail)

    def non_finite(self, rotors: np.ndarray, out) -> None:
        self.flight.parts.counters.non_finite += 1
        self.hand_over(out, "non_finite_output", math.nan, math.nan, "",
                       f"non-finite controller output {rotors.tolist()}")

    # ------------------------------------------------------------------ refusals, landing
    def refuse(self, verdict, out, phase: Phase = Phase.HOLD) -> None:
        """The health gate did not pass in time (in the hold), or a check before take-off failed
        (``phase`` preflight: the flight ends on the ground, :meth:`end_on_ground`): the
        maneuver (or, with none queued yet, the vehicle) is not flown."""
        flight, ctx = self.flight, self.flight.ctx
        kind = "maneuver" if ctx.pending else "vehicle"
        what = f"maneuver {ctx.pending[0].plan.name!r}" if ctx.pending else "the vehicle"
        violation = verdict.at(phase, ctx.vehicle_now_s)
        flight.fail(violation)
        flight.drop_pending()
        ctx.gate_wait_start_vehicle_s = None
        if phase == Phase.PREFLIGHT:
            armed = ctx.heard.status is not None and ctx.heard.status.armed
            then = "staying on the ground" + (", disarming" if armed else "")
        else:
            then = "landing" if flight.lands_when_done() else "holding"
        flight.announce(out, "refused", mm.SEVERITY_WARNING, f"{what} refused: {violation.describe()}; {then}")
        flight.note_action(f"{kind} refused, {then}")
        if phase == Phase.PREFLIGHT:
            self.end_on_ground(out, f"refused before take-off ({verdict.bound}); nothing flown")

    def end_on_ground(self, out, why: str) -> None:
        """The flight ends before take-off (a refusal, or a land request): at once when the
        vehicle is disarmed (after one more ARM_DISARM 0 when an arm request may still be on
        its way), or has never been spoken to (no dialect: nothing was sent to it); aborted when
        it was armed by another and its autopilot does not say it is on the ground (it may be
        flying: left armed). An armed vehicle is disarmed first: the preflight handler repeats
        ARM_DISARM 0, its HEARTBEAT ends the flight, or after ``ground_disarm_timeout_s``
        (injected clock) the stream is left to its failsafe (:meth:`ground_disarm_timeout`)."""
        flight, ctx = self.flight, self.flight.ctx
        ctx.landing.requested = True
        flight.drop_pending()
        st = ctx.heard.status
        disarm = mm.arm_disarm(*flight.parts.ids.target, False) if st is not None else None
        if (st is not None and st.armed and not ctx.commands.arm_requested
                and ctx.heard.landed_state != mm.mavlink2.MAV_LANDED_STATE_ON_GROUND):
            # armed by another and not known to be on the ground: it may be flying
            flight.set_phase(out, Phase.ABORTED, f"{why}; the vehicle was armed by another and is not known "
                             "to be on the ground: left armed, to its pilot and its failsafe")
            return
        if st is not None and st.armed:
            ctx.commands.ground_end_wall_s = ctx.now_wall_s
            flight.event(out, "disarming", f"{why}; disarming on the ground")
            flight.command(out, disarm, at_once=True)
            return
        if st is not None and ctx.commands.arm_requested:
            flight.command(out, disarm, at_once=True)
        flight.set_phase(out, Phase.DISARMED, why)

    def ground_disarm_timeout(self, now_wall_s: float, out) -> None:
        """A flight ending on the ground whose armed vehicle has not reported disarmed within
        ``ground_disarm_timeout_s``: the stream stops (aborted); the vehicle's own failsafe and
        automatic disarm on the ground are in charge."""
        flight, ctx = self.flight, self.flight.ctx
        limit = flight.parts.params.ground_disarm_timeout_s
        if ctx.phase != Phase.PREFLIGHT or ctx.commands.ground_end_wall_s is None:
            return
        waited = now_wall_s - ctx.commands.ground_end_wall_s
        if waited > limit:
            flight.note_action("disarm not confirmed")
            flight.set_phase(out, Phase.ABORTED, f"the vehicle did not report disarmed within {limit:g} s on the "
                             "ground; the command stream stops, its own failsafe and automatic disarm are in charge")

    def check_touchdown(self, descent_m_s: float, out) -> None:
        """A touchdown faster than the envelope allows is a hard landing (not an impact)."""
        flight = self.flight
        limit = flight.parts.envelope.max_touchdown_speed_m_s
        if descent_m_s > limit:
            flight.fail(BoundViolation("touchdown_speed", Phase.LAND, flight.ctx.heard.last_sample.time_s, math.nan,
                                       descent_m_s, limit, "m/s", "hard landing"))
            flight.announce(out, "hard_landing", mm.SEVERITY_WARNING,
                            f"touched down at {descent_m_s:.2f} m/s (limit {limit:g} m/s)")
            flight.note_action("hard landing")

    # ------------------------------------------------------------------ gaps
    def sample_gap(self, vehicle_gap_s: float, wall_gap_s: float, out) -> None:
        """A complete sample that follows the previous one by ``vehicle_gap_s`` of vehicle time
        and ``wall_gap_s`` of injected (wall) clock.

        The vehicle flew that long on a command computed from older state only when both
        are long: in lockstep the vehicle waits for the daemon (wall gaps are harmless), and a
        vehicle-time jump that arrives at once is a clock step, not a blind flight. A lockstep
        vehicle (``params.lockstep``) runs ahead only when it has no sample to be answered (a
        telemetry outage): there the vehicle time alone counts."""
        flight, ctx, parts = self.flight, self.flight.ctx, self.flight.parts
        gap = vehicle_gap_s if parts.params.lockstep else min(vehicle_gap_s, wall_gap_s)
        limit = parts.envelope.maneuver_gap_s
        if gap <= limit:
            return
        parts.counters.gaps += 1
        if ctx.phase in (Phase.RUN_IN, Phase.MANEUVER):
            self.on_violation(BoundViolation("telemetry_gap", ctx.phase, ctx.heard.last_sample.time_s, ctx.s_m, gap, limit,
                                             "s", "no complete sample for that long: the vehicle flew on an old "
                                             "command"), out)
        else:
            flight.event(out, "gap", f"{gap * 1e3:.0f} ms without a complete sample (tolerated in {ctx.phase} "
                         f"up to {parts.params.stale_timeout_s:g} s)")

    def link_lost(self, now_wall_s: float, out) -> None:
        """Judged by a running tick: no complete sample for ``stale_timeout_s``: link lost."""
        ctx, params = self.flight.ctx, self.flight.parts.params
        gap = now_wall_s - ctx.heard.last_sample_wall_s
        armed = ctx.heard.status is not None and ctx.heard.status.armed
        if armed and gap > params.stale_timeout_s and (ctx.phase in AIRBORNE or ctx.phase == Phase.PREFLIGHT):
            self.hand_over(out, "link_lost", gap, params.stale_timeout_s, "s",
                           f"stale state: no complete sample for {gap:.3f} s "
                           f"(limit {params.stale_timeout_s:g} s)")
