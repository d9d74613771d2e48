"""The flight supervisor: sans-I/O flight phases of the mavreg daemon.

Decoded MAVLink messages and the current time go in (:meth:`Supervisor.handle`,
:meth:`Supervisor.tick`); messages to send, events and controller log records come out
(:class:`Output`). No sockets, no asyncio, no wall clock: the caller injects ``now_s``
(a monotonic clock for link health and command retries), while the flight's own timing
(spool-up, ramps, holds) runs on the vehicle's ``time_boot_ms``, so a lockstep emulator
flies the same flight at any speed.

Phases::

    preflight -> takeoff -> hold -> run_in -> maneuver -> hold (at exit) -> land -> disarmed
                                 ^__________________________________|   (next upload)
    any -> aborted   (stale state, non-finite controller output, vehicle left OFFBOARD)

- **preflight** streams the idle setpoint (all rotors 0) on every complete state sample,
  arms, and asks for OFFBOARD once the stream has run ``offboard_stream_min_s``.
- **takeoff** spools the rotors up smoothly to the hover LQR's output, climbs vertically
  and moves to the hold point in front of the maneuver's entry (C^2 ramps).
- **hold** is the safe point: a pending (already planned) maneuver is switched in only here.
- **run_in** accelerates along the entry direction so that the hover LQR hands the
  vehicle to the maneuver regulator at the entry's position, velocity and acceleration.
- **maneuver** runs ``u = u(s) - K(s) w`` until ``s`` reaches the end, then a C^2 ramp
  stops the vehicle: the hold at the exit.
- **land** descends at a fixed rate, spools down on touchdown and disarms.

Stale state (no complete sample for ``stale_timeout_s`` of injected time while armed),
a non-finite controller output or the vehicle leaving OFFBOARD abort the flight: the
command stream stops for good and the vehicle's own failsafe takes over. Old commands
are never re-sent.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..config.vehicle import VehicleParams
from ..control.hover import HoverController, HoverParams, Ramp
from . import flightpath as fp
from . import messages as mm
from .state import StateAssembler, StateSample

__all__ = ["Phase", "SupervisorParams", "Event", "LogRecord", "Output", "Supervisor", "PHASE_CODES"]


class Phase:
    PREFLIGHT = "preflight"
    TAKEOFF = "takeoff"
    HOLD = "hold"
    RUN_IN = "run_in"
    MANEUVER = "maneuver"
    LAND = "land"
    DISARMED = "disarmed"
    ABORTED = "aborted"


PHASE_CODES = {p: i for i, p in enumerate(
    [Phase.PREFLIGHT, Phase.TAKEOFF, Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER, Phase.LAND,
     Phase.DISARMED, Phase.ABORTED])}
"""Integer codes of the phases in the controller log."""


@dataclass(frozen=True)
class SupervisorParams:
    """Identities, timeouts and flight-shape parameters (SI units)."""

    vehicle_system_id: int = 1
    vehicle_component_id: int = 1
    stale_timeout_s: float = 0.1
    """No complete sample for this long (injected clock) while armed: stop the stream."""
    command_retry_s: float = 0.5
    """Vehicle time between repeats of an unanswered ARM / DO_SET_MODE / DISARM."""
    offboard_stream_min_s: float = 0.7
    """Vehicle time the idle stream runs before OFFBOARD is requested (vehicle needs 0.5 s)."""
    spool_s: float = 1.0
    """Smooth thrust spool-up before take-off and spool-down after touchdown."""
    hold_before_s: float = 1.0
    hold_after_s: float = 1.0
    run_in_m: float = 0.6
    """Distance of the hold point before the entry, along the entry velocity."""
    land_speed_m_s: float = 0.3
    land_slow_altitude_m: float = 0.4
    touchdown_altitude_m: float = 0.03
    land_when_done: bool = True
    """Land after the last queued maneuver (``fly``); ``serve`` keeps holding."""
    euler_pitch_limit_rad: float = math.radians(75.0)
    hover: HoverParams = field(default_factory=HoverParams)


@dataclass(frozen=True)
class Event:
    """A phase change or notable fact, stamped with vehicle time and arc length."""

    time_s: float
    kind: str
    phase: str
    s_m: float
    detail: str

    def line(self) -> str:
        s = "" if math.isnan(self.s_m) else f" s={self.s_m:.3f} m"
        return f"t={self.time_s:8.3f} s [{self.phase}] {self.kind}{s}: {self.detail}"


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


@dataclass
class Output:
    messages: list = field(default_factory=list)
    events: list = field(default_factory=list)
    log: LogRecord | None = None


@dataclass
class Counters:
    foreign_dropped: int = 0
    samples: int = 0
    actuator_sent: int = 0
    commands_sent: int = 0
    non_finite: int = 0
    acks: int = 0


def _smoothstep(t: float) -> float:
    """C^2 blend 0 -> 1 on t in [0, 1]."""
    t = min(max(t, 0.0), 1.0)
    return t * t * t * (10.0 - 15.0 * t + 6.0 * t)


class Supervisor:
    """Flight phases around a hover LQR and the maneuver regulator.

    Parameters
    ----------
    vehicle : VehicleParams
        Design model and rotor limit.
    params : SupervisorParams
    regulator_factory : callable
        ``plan -> regulator`` with ``reset(x, s_guess)`` and ``step(x)`` returning an object
        with ``s, w, u, rotor_forces_n, in_tube, finished`` (the core's ManeuverRegulator).
    """

    def __init__(self, vehicle: VehicleParams, params: SupervisorParams, regulator_factory):
        self.vehicle = vehicle
        self.params = params
        self.hover = HoverController(vehicle, params.hover)
        self.assembler = StateAssembler(params.euler_pitch_limit_rad)
        self.regulator_factory = regulator_factory
        self.counters = Counters()
        self.phase = Phase.PREFLIGHT
        self.reason = ""
        self.vehicle_status: mm.VehicleStatus | None = None
        self.last_sample: StateSample | None = None
        self._last_sample_now: float | None = None
        self._stream_start_t: float | None = None
        self._last_cmd_t = -math.inf
        self._last_tick_now: float | None = None
        self._pending: list = []        # (plan, regulator) not yet flown
        self._active = None             # (plan, regulator) in run_in / maneuver
        self._maneuvers_done: list[str] = []
        self._ramps: list[Ramp] = []
        self._ramp_t0 = 0.0
        self._phase_t0 = 0.0
        self._ground_z = 0.0
        self._spool_down_t0: float | None = None
        self._land_requested = False
        self._s = math.nan
        self._tube_exits = 0

    # ----------------------------------------------------------------- public API
    @property
    def finished(self) -> bool:
        return self.phase in (Phase.DISARMED, Phase.ABORTED)

    @property
    def succeeded(self) -> bool:
        return self.phase == Phase.DISARMED and not self._pending and bool(self._maneuvers_done)

    def at_safe_point(self) -> bool:
        return self.phase in (Phase.PREFLIGHT, Phase.HOLD)

    def offer_plan(self, plan, now_s: float) -> Output:
        """Queue an accepted (already planned) maneuver; it starts at the next safe point."""
        out = Output()
        if self.finished:
            raise ValueError(f"the flight is over ({self.phase}); no maneuver can be queued")
        self._pending.append((plan, self.regulator_factory(plan)))
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
        return mm.daemon_heartbeat(self.phase != Phase.ABORTED)

    def status(self) -> dict:
        c = self.counters
        a = self.assembler.counters
        return {
            "phase": self.phase, "reason": self.reason, "s_m": None if math.isnan(self._s) else self._s,
            "active": None if self._active is None else self._active[0].name,
            "pending": [p.name for p, _ in self._pending], "done": list(self._maneuvers_done),
            "vehicle_mode": None if self.vehicle_status is None else self.vehicle_status.mode,
            "vehicle_armed": None if self.vehicle_status is None else self.vehicle_status.armed,
            "counters": {**c.__dict__, "state_late": a.late, "state_unmatched": a.unmatched,
                         "state_euler_refused": a.euler_near_vertical, "state_non_finite": a.non_finite},
        }

    def handle(self, msg, now_s: float) -> Output:
        """Process one decoded message from the link."""
        out = Output()
        if (msg.get_srcSystem() != self.params.vehicle_system_id
                or msg.get_srcComponent() != self.params.vehicle_component_id):
            self.counters.foreign_dropped += 1
            return out
        mtype = msg.get_type()
        if mtype == "HEARTBEAT":
            self._on_heartbeat(mm.decode_heartbeat(msg), out)
        elif mtype == "COMMAND_ACK":
            self.counters.acks += 1
            if msg.result != mm.mavlink2.MAV_RESULT_ACCEPTED:
                self._event(out, "command_refused", f"command {msg.command} result {msg.result}")
        else:
            sample = self.assembler.add(msg)
            if sample is not None:
                self.counters.samples += 1
                self._on_sample(sample, now_s, out)
        return out

    def tick(self, now_s: float) -> Output:
        """Periodic check, called every ``stale_timeout_s / 4`` or more often: stale state."""
        out = Output()
        if self.finished:
            return out
        # A tick that comes late means this process was stalled (not the link): samples may
        # be waiting unread, so staleness is judged only by ticks of a running loop.
        stalled = self._last_tick_now is not None and now_s - self._last_tick_now > self.params.stale_timeout_s / 2
        self._last_tick_now = now_s
        armed = self.vehicle_status is not None and self.vehicle_status.armed
        if (armed and not stalled and self._last_sample_now is not None
                and now_s - self._last_sample_now > self.params.stale_timeout_s):
            self._abort(out, f"stale state: no complete sample for {now_s - self._last_sample_now:.3f} s "
                        f"(limit {self.params.stale_timeout_s} s); command stream stopped")
        return out

    # ----------------------------------------------------------------- internals
    def _event(self, out: Output, kind: str, detail: str) -> None:
        t = self.last_sample.time_s if self.last_sample is not None else math.nan
        out.events.append(Event(t, kind, self.phase, self._s, detail))

    def _set_phase(self, out: Output, phase: str, detail: str) -> None:
        self.phase = phase
        if self.last_sample is not None:
            self._phase_t0 = self.last_sample.time_s
        self._event(out, "phase", detail)

    def _abort(self, out: Output, reason: str) -> None:
        self.reason = reason
        self._set_phase(out, Phase.ABORTED, reason)

    def _on_heartbeat(self, st: mm.VehicleStatus, out: Output) -> None:
        prev = self.vehicle_status
        self.vehicle_status = st
        if prev is None or prev.armed != st.armed or prev.mode != st.mode:
            self._event(out, "vehicle", f"vehicle {'armed' if st.armed else 'disarmed'}, mode {st.mode}")
        flying = self.phase in (Phase.TAKEOFF, Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER, Phase.LAND)
        if self.phase == Phase.LAND and self._spool_down_t0 is not None and not st.armed:
            self._set_phase(out, Phase.DISARMED, "touched down and disarmed")
        elif self.phase == Phase.PREFLIGHT and self._land_requested and not st.armed:
            self._set_phase(out, Phase.DISARMED, "disarmed on the ground")
        elif flying and (not st.armed or not st.offboard):
            self._abort(out, f"vehicle left OFFBOARD control (armed={st.armed}, mode {st.mode}); "
                        "its failsafe is in charge")

    def _command(self, out: Output, msg) -> None:
        """Send a command, at most once per ``command_retry_s`` of vehicle time (retries)."""
        t = self.last_sample.time_s
        if t - self._last_cmd_t >= self.params.command_retry_s or t < self._last_cmd_t:
            out.messages.append(msg)
            self._last_cmd_t = t
            self.counters.commands_sent += 1

    def _on_sample(self, sample: StateSample, now_s: float, out: Output) -> None:
        self.last_sample = sample
        self._last_sample_now = now_s
        if self.finished or self.vehicle_status is None:
            return
        t = sample.time_s
        sysid, compid = self.params.vehicle_system_id, self.params.vehicle_component_id
        if self.phase == Phase.PREFLIGHT:
            if self._stream_start_t is None:
                self._stream_start_t = t
            self._send_rotors(np.zeros(4), now_s, out)
            if self._land_requested:
                if self.vehicle_status.armed:
                    self._command(out, mm.arm_disarm(sysid, compid, False))
                return
            if not self._pending:
                return
            st = self.vehicle_status
            if not st.armed:
                self._command(out, mm.arm_disarm(sysid, compid, True))
            elif not st.offboard:
                if t - self._stream_start_t >= self.params.offboard_stream_min_s:
                    self._command(out, mm.set_offboard(sysid, compid))
            else:
                self._start_takeoff(sample, out)
            return
        rotors, record = self._control(sample, out)
        if self.finished:
            return
        if not np.all(np.isfinite(rotors)):
            self.counters.non_finite += 1
            self._abort(out, f"non-finite controller output {rotors.tolist()}; command stream stopped")
            return
        self._send_rotors(rotors, now_s, out)
        out.log = record

    def _send_rotors(self, rotor_forces_n: np.ndarray, now_s: float, out: Output) -> None:
        controls = np.clip(rotor_forces_n / self.vehicle.max_rotor_thrust_n, 0.0, 1.0)
        out.messages.append(mm.actuator_target(int(now_s * 1e6), self.params.vehicle_system_id,
                                               self.params.vehicle_component_id, controls))
        self.counters.actuator_sent += 1

    # ------------------------------------------------------------ phase control
    def _start_ramps(self, ramps: list[Ramp], t: float) -> None:
        self._ramps = list(ramps)
        self._ramp_t0 = t

    def _start_takeoff(self, sample: StateSample, out: Output) -> None:
        plan = self._pending[0][0]
        entry = fp.entry_of(plan, self.params.hover, self.params.run_in_m)
        p = sample.x[:3].copy()
        self._ground_z = float(p[2])
        ramps = fp.takeoff_ramps(p, float(sample.x[5]), entry, self.params.spool_s, self.params.hover)
        self._set_phase(out, Phase.TAKEOFF, f"take-off from z={p[2]:.2f} m to hold point "
                        f"{np.round(entry.hold_m, 3).tolist()} for {plan.name!r}")
        self._start_ramps(ramps, sample.time_s)

    def _hover_control(self, sample: StateSample):
        t = sample.time_s - self._ramp_t0
        while len(self._ramps) > 1 and self._ramps[0].finished(t):
            self._ramp_t0 += self._ramps[0].duration_s
            t -= self._ramps[0].duration_s
            self._ramps.pop(0)
        ramp = self._ramps[0]
        return self.hover.step(sample.x, ramp, t), len(self._ramps) == 1 and ramp.finished(t)

    def _record(self, sample, s, w, u, rotors) -> LogRecord:
        return LogRecord(sample.time_s, self.phase, s, np.asarray(w, float), np.asarray(u, float),
                         np.asarray(rotors, float), sample.x.copy())

    def _control(self, sample: StateSample, out: Output):
        t = sample.time_s
        nan11 = np.full(11, np.nan)
        if self.phase == Phase.MANEUVER:
            plan, reg = self._active
            r = reg.step(sample.x)
            self._s = float(r.s)
            if not r.in_tube:
                self._tube_exits += 1
                if self._tube_exits == 1:
                    self._event(out, "tube", "left the regulation tube (counting)")
            rotors = np.asarray(r.rotor_forces_n, dtype=float)
            record = self._record(sample, r.s, r.w, r.u, rotors)
            if r.finished and np.all(np.isfinite(rotors)):
                self._maneuvers_done.append(plan.name)
                self._active = None
                self._start_exit_hold(sample, out)
            return rotors, record
        ho, ramp_done = self._hover_control(sample)
        rotors = ho.rotor_forces_n
        if self.phase == Phase.TAKEOFF and t - self._phase_t0 < self.params.spool_s:
            rotors = rotors * _smoothstep((t - self._phase_t0) / self.params.spool_s)
        elif self.phase == Phase.LAND:
            rotors = self._land_logic(sample, rotors, out)
        record = self._record(sample, math.nan, nan11, ho.u, rotors)
        if self.phase == Phase.TAKEOFF and ramp_done:
            self._set_phase(out, Phase.HOLD, "take-off complete, holding")
        elif (self.phase == Phase.HOLD and ramp_done
              and t - max(self._phase_t0, self._ramp_t0 + self._ramps[0].duration_s) >= self._hold_time()):
            self._leave_hold(sample, out)
        elif self.phase == Phase.RUN_IN and ramp_done:
            plan, reg = self._active
            reg.reset(sample.x, s_guess=0.0)
            self._s = 0.0
            self._tube_exits = 0
            self._set_phase(out, Phase.MANEUVER, f"maneuver {plan.name!r} begins")
        return rotors, record

    def _hold_time(self) -> float:
        return self.params.hold_after_s if self._maneuvers_done else self.params.hold_before_s

    def _leave_hold(self, sample: StateSample, out: Output) -> None:
        hp = self.params.hover
        p = sample.x[:3]
        hold_p = self._ramps[-1].end_position_m
        hold_yaw = self._ramps[-1].end_yaw_rad
        if self._pending and not self._land_requested:
            plan, reg = self._pending.pop(0)
            self._active = (plan, reg)
            entry = fp.entry_of(plan, hp, self.params.run_in_m)
            ramps = fp.run_in_ramps(hold_p, hold_yaw, entry, hp)
            self._s = math.nan
            self._set_phase(out, Phase.RUN_IN, f"run-in to the entry of {plan.name!r} from "
                            f"{np.round(p, 3).tolist()}")
            self._start_ramps(ramps, sample.time_s)
        elif self.params.land_when_done or self._land_requested:
            ramp = fp.land_ramp(hold_p, hold_yaw, self._ground_z, self.params.land_slow_altitude_m,
                                self.params.land_speed_m_s, hp)
            self._s = math.nan
            self._set_phase(out, Phase.LAND, f"landing from {np.round(p, 3).tolist()}")
            self._start_ramps([ramp], sample.time_s)

    def _start_exit_hold(self, sample: StateSample, out: Output) -> None:
        p = sample.x[:3]
        v = sample.velocity_ned_m_s
        ramp = fp.stop_ramp(p, v, float(sample.x[5]), self.params.hover)
        self._set_phase(out, Phase.HOLD, f"maneuver finished at {np.round(p, 3).tolist()}, "
                        f"{float(np.linalg.norm(v)):.2f} m/s; stopping and holding at the exit")
        self._start_ramps([ramp], sample.time_s)

    def _land_logic(self, sample: StateSample, rotors: np.ndarray, out: Output) -> np.ndarray:
        t = sample.time_s
        altitude = self._ground_z - sample.x[2]
        if self._spool_down_t0 is None:
            if altitude <= self.params.touchdown_altitude_m:
                self._spool_down_t0 = t
                self._event(out, "touchdown", f"touchdown at altitude {altitude:.3f} m; spooling down")
            else:
                return rotors
        blend = 1.0 - _smoothstep((t - self._spool_down_t0) / self.params.spool_s)
        if blend <= 0.0:
            st = self.vehicle_status
            if st is not None and st.armed:
                self._command(out, mm.arm_disarm(
                    self.params.vehicle_system_id, self.params.vehicle_component_id, False))
        return rotors * blend
