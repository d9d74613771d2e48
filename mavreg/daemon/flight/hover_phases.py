"""The phases flown by the hover LQR on a ramp: take-off, hold (with the health gate), run-in,
landing (sans-I/O).

Each is a handler with ``control(sample, x, out) -> (rotor forces, log record, tracking)``
(:class:`~mavreg.daemon.flight.handlers.AirborneHandler`); :class:`HoverPhase` flies the current
ramp and each phase adds what is its own: the spool-up, the gate and the way out of a hold,
the maneuver's start, the touchdown and the disarm. The table of all phases is
:data:`mavreg.daemon.flight.handlers.HANDLERS`.
"""
from __future__ import annotations

import collections
import math

import numpy as np

from ...model.mixer import Mixer
from . import flightpath as fp
from ..vehicle import messages as mm
from .verbs import NAN11, Flight, angle_between, norm3, smoothstep
from .context import DescentPoint
from .excitation import EXCITATION_END, EXCITATION_START
from .gate import plan_outside_envelope
from .monitor import Tracking
from .phases import Phase
from .safety import SafetyPolicy

__all__ = ["HoverPhase", "Takeoff", "Hold", "RunIn", "Land"]

_OBSERVE_AFTER_LIFTOFF_M = 0.02
"""Height above the take-off point from which the disturbance observer learns on take-off:
at once (a 6 m/s wind tilts the vehicle 20 deg within half a second of lift-off)."""
_OBSERVE_UNTIL_LANDING_M = 0.5
"""Height above the take-off point down to which it learns while landing (a descent through
a wind changes the drag; the ground's reaction near touchdown is no force to learn)."""


class HoverPhase:
    """A phase flown by the hover LQR on the current ramp.

    Subclasses set :attr:`observe_above_m` and override :meth:`shape` (the rotor forces and
    the tracking judged) and :meth:`ramp_done` (the way out of the phase)."""

    observe_above_m: float | None = None
    """The observer learns only this far above the take-off point (None: as the phase says)."""

    def __init__(self, flight: Flight, safety: SafetyPolicy):
        self.flight = flight
        self.safety = safety

    def control(self, sample, x, out):
        flight, ctx = self.flight, self.flight.ctx
        if self.observe_above_m is not None:     # the observer learns clear of the ground
            flight.parts.forecaster.observing = ctx.ground_z_m - float(x[2]) > self.observe_above_m
        ho, ramp_done = flight.hover_step(sample, x)
        e = ho.error
        tracking = Tracking(norm3(e, 0), angle_between(x[3:6], x[3:6] - e[3:6]), norm3(e, 9))
        rotors, tracking = self.shape(sample, ho.rotor_forces_n, tracking, out)
        record = flight.record(sample, math.nan, NAN11, ho.u, rotors)
        if ramp_done:
            self.ramp_done(sample, x, rotors, tracking, out)
        return rotors, record, tracking

    def shape(self, sample, rotors, tracking, out):
        """(rotor forces to send, tracking to judge or None)."""
        return rotors, tracking

    def ramp_done(self, sample, x, rotors, tracking, out) -> None:
        """The last ramp of the phase has been flown."""


class Takeoff(HoverPhase):
    """Spool up, climb to the hold point before the maneuver's entry."""

    observe_above_m = _OBSERVE_AFTER_LIFTOFF_M

    def shape(self, sample, rotors, tracking, out):
        t_phase = sample.time_s - self.flight.ctx.phase_start_vehicle_s
        spool_s = self.flight.parts.params.spool_s
        if t_phase < spool_s:
            rotors = rotors * smoothstep(t_phase / spool_s)
        return rotors, tracking

    def ramp_done(self, sample, x, rotors, tracking, out) -> None:
        self.flight.set_phase(out, Phase.HOLD, "take-off complete, holding")


class Hold(HoverPhase):
    """The safe point: a queued maneuver starts here once the health gate passes; with
    nothing to fly, land (``fly``) or hold on (``serve``). Before the first maneuver, the
    identification excitation when asked for (:mod:`mavreg.daemon.flight.excitation`): its doublets
    first, then the hold and the gate as always."""

    def __init__(self, flight: Flight, safety: SafetyPolicy):
        super().__init__(flight, safety)
        mixer = Mixer.from_vehicle(flight.parts.vehicle)
        self._mixer, self._unmix = mixer.matrix, mixer.inverse

    def shape(self, sample, rotors, tracking, out):
        """In a doublet, the hover LQR's torque about the excited axis is left out (the
        doublet's rate goes out there instead, :meth:`RateOutput.command`), so that fighting
        the doublet does not saturate the rotor commands the monitor counts."""
        ctx = self.flight.ctx
        ctx.excitation.rate_step = None
        exc = self.flight.parts.params.excitation
        if exc is None or ctx.excitation.start_vehicle_s is None or ctx.excitation.end_vehicle_s is not None:
            return rotors, tracking
        step = exc.rate_at(sample.time_s - ctx.excitation.start_vehicle_s)
        if step is not None:
            ctx.excitation.rate_step = step
            wrench = self._mixer @ np.asarray(rotors, dtype=float)
            wrench[1 + step[0]] = 0.0
            rotors = self._unmix @ wrench
        return rotors, tracking

    def ramp_done(self, sample, x, rotors, tracking, out) -> None:
        ctx, params = self.flight.ctx, self.flight.parts.params
        t = sample.time_s
        if self._exciting(t, out):
            return                          # the gate and the hold's time wait for its end
        self.flight.parts.gate.observe(t, tracking.position_error_m, tracking.attitude_error_rad, rotors)
        hold_s = params.hold_after_s if ctx.maneuvers_done else params.hold_before_s
        since = max(ctx.phase_start_vehicle_s, ctx.ramp_start_vehicle_s + ctx.ramps[0].duration_s)
        if ctx.excitation.end_vehicle_s is not None:
            since = max(since, ctx.excitation.end_vehicle_s)
        if t - since >= hold_s:
            self._leave(sample, out)

    def _exciting(self, t: float, out) -> bool:
        """Start, run or end the excitation at vehicle time ``t``: True while it runs. Only
        before the first maneuver, with one pending and no landing asked for; once a flight."""
        flight, ctx = self.flight, self.flight.ctx
        exc = flight.parts.params.excitation
        if exc is None or ctx.excitation.end_vehicle_s is not None:
            return False
        wanted = bool(ctx.pending) and not ctx.maneuvers_done and not ctx.landing.requested
        if ctx.excitation.start_vehicle_s is None:
            if not wanted:
                return False
            ctx.excitation.start_vehicle_s = t
            flight.parts.forecaster.observing = False    # the doublets are no disturbance to learn
            flight.announce(out, "excitation", mm.SEVERITY_INFO, f"{EXCITATION_START} {exc.describe()}")
            return True
        elapsed = t - ctx.excitation.start_vehicle_s
        if wanted and elapsed < exc.duration_s:
            return True
        ctx.excitation.end_vehicle_s = t
        ctx.excitation.rate_step = None
        flight.parts.forecaster.observing = True
        flight.parts.gate.reset()                        # the gate judges the hold after it
        flight.announce(out, "excitation", mm.SEVERITY_INFO,
                        f"{EXCITATION_END} {'done' if elapsed >= exc.duration_s else 'cut short'} "
                        f"after {elapsed:.1f} s; holding")
        return False

    def _leave(self, sample, out) -> None:
        flight, ctx = self.flight, self.flight.ctx
        t = sample.time_s
        if ctx.pending and not ctx.landing.requested:
            verdict = self._gate_verdict()
            if verdict is None:
                return                                     # not a full window yet: hold on
            if not verdict.ok:
                if ctx.gate_wait_start_vehicle_s is None:
                    ctx.gate_wait_start_vehicle_s = t
                if t - ctx.gate_wait_start_vehicle_s < flight.parts.envelope.gate.timeout_s:
                    return                                 # hold on: it may settle
                self.safety.refuse(verdict, out)
                if ctx.pending:
                    return
            else:
                self._start_run_in(sample, out)
                return
        if flight.lands_when_done():
            hold = ctx.ramps[-1]
            ctx.s_m = math.nan
            flight.set_phase(out, Phase.LAND, f"landing from {np.round(sample.x[:3], 3).tolist()}")
            flight.start_landing(hold.end_position_m, hold.end_yaw_rad, t)

    def _gate_verdict(self):
        """The gate's verdict on the first pending plan (None: the window is not full yet)."""
        parts = self.flight.parts
        if not parts.gate.ready():
            return None
        plan, pts = self.flight.ctx.pending[0].plan, self.flight.ctx.pending[0].points
        bad = plan_outside_envelope(pts, parts.monitor.origin, parts.envelope)
        return bad if bad is not None else parts.gate.evaluate(self.flight.gate_margin(plan))

    def _start_run_in(self, sample, out) -> None:
        flight, ctx, params = self.flight, self.flight.ctx, self.flight.parts.params
        hold = ctx.ramps[-1]
        plan = flight.start_next().plan
        ctx.gate_wait_start_vehicle_s = None
        entry = fp.entry_of(plan, params.hover, params.run_in_m, params.entry_offset_m)
        ramps = fp.run_in_ramps(hold.end_position_m, hold.end_yaw_rad, entry, params.hover)
        ctx.s_m = math.nan
        flight.set_phase(out, Phase.RUN_IN, f"health gate passed; run-in to the entry of "
                         f"{plan.name!r} from {np.round(sample.x[:3], 3).tolist()}")
        flight.start_ramps(ramps, sample.time_s)


class RunIn(HoverPhase):
    """From the hold point to the maneuver's entry at its speed; then the regulator takes over."""

    def ramp_done(self, sample, x, rotors, tracking, out) -> None:
        flight, ctx = self.flight, self.flight.ctx
        plan, reg = ctx.active.plan, ctx.active.regulator
        reg.reset(x, s_guess=0.0, rotor_forces_n=ctx.heard.forecast.rotor_forces_n)
        ctx.s_m = 0.0
        flight.set_phase(out, Phase.MANEUVER, f"maneuver {plan.name!r} begins")


def touched_down(descent: collections.deque[DescentPoint], t_s: float, vz_m_s: float, altitude_m: float,
                 params) -> float | None:
    """The touchdown speed (m/s, down positive) once the ground has stopped the landing's
    descent, else None.

    ``descent`` keeps the last second (appended here). Touchdown: within
    ``params.touchdown_band_m`` of the take-off height, every vertical speed of the last
    ``params.touchdown_settle_s`` below ``params.touchdown_stall_m_s`` while the landing asks
    for a descent, after it sank faster than that (or for a whole second: a landing begun at
    the ground). The speed is the fastest descent of the second before it."""
    descent.append(DescentPoint(t_s, vz_m_s))
    while descent and t_s - descent[0].t_vehicle_s > 1.0:
        descent.popleft()
    if altitude_m > params.touchdown_band_m or t_s - descent[0].t_vehicle_s < params.touchdown_settle_s:
        return None
    if any(d.down_m_s >= params.touchdown_stall_m_s for d in descent if t_s - d.t_vehicle_s <= params.touchdown_settle_s):
        return None
    fastest = max(d.down_m_s for d in descent)
    if fastest < params.touchdown_stall_m_s and t_s - descent[0].t_vehicle_s < 0.9:
        return None          # not yet sinking (a landing begun low): a stall says nothing yet
    return fastest


class Land(HoverPhase):
    """Descend to the take-off altitude (the hover LQR, or the recovery controller after a
    recovery that could not settle); at touchdown spool down, then disarm."""

    observe_above_m = _OBSERVE_UNTIL_LANDING_M

    def control(self, sample, x, out):
        if self.flight.ctx.recovery.landing:
            rotors, record, _, _ = self.flight.recovery_step(sample, x)
            return self._touchdown(sample, rotors, out), record, None
        return super().control(sample, x, out)

    def shape(self, sample, rotors, tracking, out):
        rotors = self._touchdown(sample, rotors, out)
        if self.flight.ctx.landing.spool_down_start_vehicle_s is not None:
            tracking = None          # on the ground: the reference sinks on without it
        return rotors, tracking

    def _touchdown(self, sample, rotors: np.ndarray, out) -> np.ndarray:
        """The rotor forces to send: as asked until touchdown, then spooled down to idle; a
        disarm (or the autopilot's landing mode) once idle."""
        flight, ctx, params = self.flight, self.flight.ctx, self.flight.parts.params
        t = sample.time_s
        altitude = ctx.ground_z_m - sample.x[2]
        if ctx.landing.spool_down_start_vehicle_s is None:
            speed = touched_down(ctx.landing.descent, t, float(sample.velocity_ned_m_s[2]), altitude, params)
            if speed is not None:
                ctx.landing.spool_down_start_vehicle_s = t
                ctx.landing.touchdown_speed_m_s = speed
                flight.event(out, "touchdown", f"touchdown at altitude {altitude:.3f} m, descending at "
                             f"{speed:.2f} m/s; spooling down")
                self.safety.check_touchdown(speed, out)
            else:
                return rotors
        blend = 1.0 - smoothstep((t - ctx.landing.spool_down_start_vehicle_s) / params.spool_s)
        if blend <= 0.0:
            st = ctx.heard.status
            if st is not None and st.armed:
                idle_s = t - ctx.landing.spool_down_start_vehicle_s - params.spool_s
                flight.command(out, self._ground_disarm(idle_s, st))
        return rotors * blend

    def _ground_disarm(self, idle_s: float, st):
        """Touched down, motors idle for ``idle_s``: ask for a disarm; after
        ``land_mode_after_s`` (at once where the dialect says so: ArduCopter refuses a disarm in
        GUIDED until its land detector has seen the landing, which under thrust set-points it
        rarely does), ask for the autopilot's own landing mode instead, which disarms on the
        ground by itself."""
        params = self.flight.parts.params
        dialect = self.flight.parts.autopilot.dialect
        sysid, compid = self.flight.parts.ids.target
        wait_s = 0.0 if dialect.disarm_by_land_mode else params.land_mode_after_s
        if idle_s < wait_s or st.mode == dialect.land_mode:
            return mm.arm_disarm(sysid, compid, False)
        self.flight.ctx.landing.mode_requested = True
        return dialect.set_land_mode(sysid, compid)
