"""The supervisor's safety actions, in order of severity, and its gap policy.

A mixin of :class:`mavreg.daemon.supervisor.Supervisor` (it shares its state).

The rule: **the motors are never stopped in the air because a bound fired.** A safety
action must not be worse than the fault it answers, and a vehicle whose motors stop falls.

- **Recover** (:meth:`SafetyActions._recover`): a bound of the envelope is violated in
  flight. The maneuver (or hover) control is left for the recovery controller
  (:mod:`mavreg.control.recovery`): level, brake, climb to a safe altitude, hold; then land
  (``fly``) or hold and wait for an upload (``serve``). Pending maneuvers are dropped. A
  recovery is judged over ``recovery.timeout_s``, not by one sample: a bound that fires
  while it flies is announced once and the recovery goes on.
- **Land with the recovery controller** (:meth:`SafetyActions._recovery_land`): a recovery
  that has not settled within its time, a violation after ``max_recoveries``, or a
  violation near the ground (within ``impact_altitude_m``). The recovery controller,
  which holds any attitude, descends at the landing speed; at touchdown the rotors spool
  down and the vehicle is disarmed, as in a normal landing. Bounds that fire on the way
  down are announced once; the landing goes on.
- **Stop the motors** (:meth:`SafetyActions._terminate`): only after an impact, i.e. ground
  contact confirmed by the telemetry (within ``impact_altitude_m`` of the take-off altitude
  and descending or moving faster than the impact bounds, an acceleration spike there, or
  thrust contradicted there). COMMAND_LONG ARM_DISARM param1 = 0, param2 = 21196 (forced),
  repeated every ``disarm_retry_s`` until acknowledged or reported disarmed; the actuator
  stream stops for good. No thrust is ever commanded again.
- **Hand over** (:meth:`SafetyActions._hand_over`): the link is lost (no sample for
  ``stale_timeout_s``), the controller output is not finite, or the vehicle left OFFBOARD:
  the stream stops for good and the vehicle's failsafe flies.
- **Refuse** (:meth:`SafetyActions._refuse`): the health gate does not pass within its time:
  the maneuver is not flown; hold, then land (``fly``) or keep holding (``serve``).

Every action is an :class:`~mavreg.daemon.phases.Event`, a log line (the app prints events)
and a STATUSTEXT to the vehicle (CRITICAL for recover / land / stop / hand over, WARNING for
a refusal or a hard landing); the first bound violated is kept as the flight's
:class:`~mavreg.daemon.phases.Failure`, with every action taken after it.

Gaps (docs/safety.md): a complete sample that follows the previous one by more than
``maneuver_gap_s`` of both vehicle time and injected clock starts a recovery in run-in or
maneuver, and is counted (and tolerated) elsewhere; a running tick that has seen no sample
for ``stale_timeout_s`` (injected clock) hands over, in every armed phase.
"""
from __future__ import annotations

import math

import numpy as np

from . import messages as mm
from .monitor import Violation
from .phases import AIRBORNE, Failure, Phase

__all__ = ["SafetyActions"]


class SafetyActions:
    """Safety actions of the supervisor (see the module docstring)."""

    # ------------------------------------------------------------------ outcome
    def _fail(self, bound: str, phase: str, t_s: float, s_m: float, value: float, limit: float,
              unit: str, detail: str) -> None:
        """Keep the first failure of the flight (later ones only add actions)."""
        if self.failure is None:
            self.failure = Failure(bound, phase, t_s, s_m, value, limit, unit, detail, "")

    def _note_action(self, action: str) -> None:
        self._actions.append(action)
        if self.failure is not None:
            from dataclasses import replace
            self.failure = replace(self.failure, action=", then ".join(self._actions))

    def _announce(self, out, kind: str, severity: int, text: str) -> None:
        """An event, and the same words in a STATUSTEXT to the vehicle (and the .tlog)."""
        self._event(out, kind, text)
        for msg in mm.statustext(severity, f"mavreg {kind}: {text}", self._statustext_id()):
            out.messages.append(msg)
            self.counters.statustexts += 1

    def _statustext_id(self) -> int:
        self._text_id = self._text_id % 65535 + 1
        return self._text_id

    # ------------------------------------------------------------------ violations
    def _violation(self, v: Violation, out) -> None:
        """Act on a violated bound: recover, land with the recovery controller, or (after an
        impact only) stop the motors."""
        self._fail(v.bound, v.phase, v.t_s, v.s_m, v.value, v.limit, v.unit, v.detail)
        sample = self.last_sample
        at_ground = sample is not None and self.monitor.altitude_m(sample.x[:3]) <= self.envelope.impact_altitude_m
        if v.impact:
            self._terminate(out, f"impact: {v.describe()}")
        elif self._recovery_landing:
            self._note_bound(out, v, "landing on")
        elif self.phase == Phase.RECOVER and v.bound == "recovery_timeout":
            self._recovery_land(out, f"recovery not settled: {v.describe()}")
        elif self.phase == Phase.RECOVER:
            self._note_bound(out, v, "recovery goes on, judged over "
                             f"{self.envelope.recovery.timeout_s:g} s")
        elif at_ground:
            self._recovery_land(out, f"at the ground: {v.describe()}")
        elif self._recoveries >= self.envelope.recovery.max_recoveries:
            self._recovery_land(out, f"recovery {self._recoveries + 1} not allowed: {v.describe()}")
        else:
            self._recover(v, out)

    def _note_bound(self, out, v: Violation, then: str) -> None:
        """A bound that fired while the recovery controller flies: announced once per bound."""
        if v.bound in self._noted_bounds:
            return
        self._noted_bounds.add(v.bound)
        self._announce(out, "bound", mm.SEVERITY_WARNING, f"{v.describe()}; {then}")

    def _to_recovery_controller(self, start: bool) -> list:
        """The recovery controller takes over (``start``: from the last sample): the maneuver
        and pending ones are dropped; their names are returned."""
        if start:
            s = self.last_sample
            self.recovery.start(s.x[:3], s.velocity_ned_m_s, s.rotation, self._ground_z)
        dropped = [p.name for p, _, _ in self._pending]
        self._pending.clear()
        self._active = None
        self._noted_bounds = set()
        self._s = math.nan
        return dropped

    def _recover(self, v: Violation, out) -> None:
        self._recoveries += 1
        dropped = self._to_recovery_controller(start=True)
        self._settled_since = None
        safe = self.envelope.recovery.safe_altitude_m
        self._announce(out, "recover", mm.SEVERITY_CRITICAL, f"{v.describe()}; recovering: level, brake, "
                       f"climb to {safe:g} m, hold" + (f" (dropped {dropped})" if dropped else ""))
        self._note_action("recovery")
        self._set_phase(out, Phase.RECOVER, f"recovery {self._recoveries} begins")

    def _recovery_land(self, out, why: str) -> None:
        """Land where the vehicle is with the recovery controller (any attitude), at the
        landing speed; the landing's touchdown, spool-down and disarm follow."""
        self._to_recovery_controller(start=self.phase != Phase.RECOVER)
        self.recovery.land(self._ground_z, self.params.land_speed_m_s)
        self._recovery_landing = True
        self._announce(out, "recovery_land", mm.SEVERITY_CRITICAL,
                       f"{why}; landing with the recovery controller at {self.params.land_speed_m_s:g} m/s")
        self._note_action("landing (recovery controller)")
        self._set_phase(out, Phase.LAND, "landing where it is with the recovery controller")

    def _recovery_timeout(self, t_s: float):
        """A Violation when the recovery has not settled within its time limit."""
        limit = self.envelope.recovery.timeout_s
        if self.phase == Phase.RECOVER and t_s - self._phase_t0 > limit:
            return Violation("recovery_timeout", Phase.RECOVER, t_s, math.nan, t_s - self._phase_t0, limit, "s",
                             "not level, slow and at the safe altitude in time")
        return None

    def _terminate(self, out, why: str) -> None:
        """Stop the motors: forced disarm until confirmed, no actuator stream ever again.
        Only after an impact (ground contact), never in the air."""
        self._announce(out, "motors_stopped", mm.SEVERITY_CRITICAL, f"{why}; forced disarm")
        self._note_action("motors stopped (forced disarm)")
        self._active = None
        self._pending.clear()
        self._set_phase(out, Phase.TERMINATE, "forced disarm, repeated until the vehicle confirms it; "
                        "no rotor command is sent any more")
        self._terminate_t0 = self._now_s
        self._disarm_sent = -math.inf
        self._terminate_step(self._now_s, out)

    def _terminate_step(self, now_s: float, out) -> None:
        """Repeat the forced disarm; give up (stream stopped anyway) after ``terminate_timeout_s``."""
        if now_s - self._terminate_t0 > self.params.terminate_timeout_s:
            self._note_action("disarm not confirmed")
            self._set_phase(out, Phase.ABORTED, f"forced disarm not confirmed within "
                            f"{self.params.terminate_timeout_s:g} s; the vehicle's failsafe is in charge")
            return
        if now_s - self._disarm_sent >= self.params.disarm_retry_s:
            out.messages.append(mm.force_disarm(self.params.vehicle_system_id, self.params.vehicle_component_id))
            self.counters.commands_sent += 1
            self._disarm_sent = now_s

    def _disarm_confirmed(self, out, how: str) -> None:
        self._note_action(f"disarmed ({how})")
        self._set_phase(out, Phase.DISARMED, f"motors stopped: {how}")

    def _hand_over(self, out, bound: str, value: float, limit: float, unit: str, detail: str) -> None:
        """Stop the stream for good: the vehicle's failsafe flies."""
        t = self.last_sample.time_s if self.last_sample is not None else math.nan
        self._fail(bound, self.phase, t, self._s, value, limit, unit, detail)
        self.reason = detail
        self._announce(out, "hand_over", mm.SEVERITY_CRITICAL, f"{detail}; command stream stopped, "
                       "the vehicle's failsafe is in charge")
        self._note_action("command stream stopped (vehicle failsafe)")
        self._set_phase(out, Phase.ABORTED, detail)

    def _refuse(self, verdict, out, phase: str = Phase.HOLD) -> None:
        """The health gate did not pass in time (in the hold), or a check before take-off failed
        (``phase`` preflight: the vehicle stays on the ground and is disarmed): the maneuver is
        not flown."""
        plan = self._pending[0][0]
        t = self.last_sample.time_s
        self._fail(verdict.bound, phase, t, math.nan, verdict.value, verdict.limit, verdict.unit,
                   verdict.detail)
        self._pending.clear()
        self._gate_wait_t0 = None
        if phase == Phase.PREFLIGHT:
            then = "staying on the ground, disarming"
            self._land_requested = True
        else:
            then = "landing" if self.params.land_when_done or self._land_requested else "holding"
        self._announce(out, "refused", mm.SEVERITY_WARNING, f"maneuver {plan.name!r} refused by the health gate: "
                       f"{verdict.bound} {verdict.value:.3g} {verdict.unit} (limit {verdict.limit:.3g}); "
                       f"{verdict.detail}; {then}")
        self._note_action(f"maneuver refused, {then}")

    def _check_touchdown(self, descent_m_s: float, out) -> None:
        limit = self.envelope.max_touchdown_speed_m_s
        if descent_m_s > limit:
            t = self.last_sample.time_s
            self._fail("touchdown_speed", Phase.LAND, t, math.nan, descent_m_s, limit, "m/s", "hard landing")
            self._announce(out, "hard_landing", mm.SEVERITY_WARNING,
                           f"touched down at {descent_m_s:.2f} m/s (limit {limit:g} m/s)")
            self._note_action("hard landing")

    # ------------------------------------------------------------------ gaps
    def _gap(self, vehicle_gap_s: float, wall_gap_s: float, out) -> None:
        """A complete sample that follows the previous one by ``vehicle_gap_s`` of vehicle time
        and ``wall_gap_s`` of injected (wall) clock.

        The vehicle flew that long on a command computed from older state only when both
        are long: in lockstep the vehicle waits for the daemon (wall gaps are harmless), and a
        vehicle-time jump that arrives at once is a clock step, not a blind flight. A lockstep
        vehicle (``params.lockstep``) runs ahead only when it has no sample to be answered (a
        telemetry outage): there the vehicle time alone counts."""
        gap = vehicle_gap_s if self.params.lockstep else min(vehicle_gap_s, wall_gap_s)
        if gap <= self.envelope.maneuver_gap_s:
            return
        self.counters.gaps += 1
        t = self.last_sample.time_s
        if self.phase in (Phase.RUN_IN, Phase.MANEUVER):
            self._violation(Violation("telemetry_gap", self.phase, t, self._s, gap, self.envelope.maneuver_gap_s,
                                      "s", "no complete sample for that long: the vehicle flew on an old "
                                      "command"), out)
        else:
            self._event(out, "gap", f"{gap * 1e3:.0f} ms without a complete sample (tolerated in {self.phase} "
                        f"up to {self.params.stale_timeout_s:g} s)")

    def _wall_clock_gap(self, now_s: float, out) -> None:
        """Judged by a running tick: no complete sample for ``stale_timeout_s``: link lost."""
        gap = now_s - self._last_sample_now
        armed = self.vehicle_status is not None and self.vehicle_status.armed
        if armed and gap > self.params.stale_timeout_s and (self.phase in AIRBORNE or self.phase == Phase.PREFLIGHT):
            self._hand_over(out, "link_lost", gap, self.params.stale_timeout_s, "s",
                            f"stale state: no complete sample for {gap:.3f} s "
                            f"(limit {self.params.stale_timeout_s:g} s)")

    def _non_finite(self, rotors: np.ndarray, out) -> None:
        self.counters.non_finite += 1
        self._hand_over(out, "non_finite_output", math.nan, math.nan, "",
                        f"non-finite controller output {rotors.tolist()}")
