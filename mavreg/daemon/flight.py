"""The supervisor's flight phases: what each phase commands and when it hands over.

A mixin of :class:`mavreg.daemon.supervisor.Supervisor` (it shares its state): preflight,
take-off, hold (with the health gate), run-in, maneuver, exit hold, landing, and the
recovery phase's control. Safety actions (recover, stop the motors, hand over to the
vehicle) are in :mod:`mavreg.daemon.safety`; the envelope checks in
:mod:`mavreg.daemon.monitor`.
"""
from __future__ import annotations

import math

import numpy as np

from ..control.hover import hold_ramp
from ..model.rotation import rpy_to_matrix
from ..model.rotation_kernel import rpy_matrix
from . import flightpath as fp
from . import messages as mm
from .gate import GateVerdict, MarginCheck, delay_margin_of, plan_outside_envelope, sampling_verdict
from .monitor import Tracking
from .phases import LogRecord, Phase

__all__ = ["FlightPhases", "smoothstep", "angle_between"]

_NAN11 = np.full(11, np.nan)


_OBSERVE_AFTER_LIFTOFF_M = 0.02
"""Height above the take-off point from which the disturbance observer learns on take-off:
at once (a 6 m/s wind tilts the vehicle 20 deg within half a second of lift-off)."""
_OBSERVE_UNTIL_LANDING_M = 0.5
"""Height above the take-off point down to which it learns while landing (a descent through
a wind changes the drag; the ground's reaction near touchdown is no force to learn)."""


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


def _norm3(v, i: int) -> float:
    """Euclidean norm of v[i:i+3]."""
    a, b, c = float(v[i]), float(v[i + 1]), float(v[i + 2])
    return math.sqrt(a * a + b * b + c * c)


class FlightPhases:
    """Phase control of the supervisor (see the module docstring)."""

    # ------------------------------------------------------------------ preflight
    def _preflight(self, sample, now_s: float, out) -> None:
        t = sample.time_s
        sysid, compid = self.params.vehicle_system_id, self.params.vehicle_component_id
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
            plan, regulator, points = self._pending[0]
            bad = plan_outside_envelope(points, sample.x[:3], self.envelope) or sampling_verdict(plan, regulator)
            if bad is None:                                # the autopilot's parameters, its telemetry
                bad = self.autopilot.ready(t, out.messages)
                if bad is None:
                    return
                bad = None if bad.ok else bad
            if bad is not None:                            # as the hold's gate would, before take-off
                self._refuse(bad, out, Phase.PREFLIGHT)
                return
            if not self.delay.known:
                waited = t - self._stream_start_t
                if waited < self.params.timesync_wait_s:
                    return                                 # TIMESYNC requests go out with the stream
                self._refuse(GateVerdict(
                    False, "gate_no_timesync", waited, self.params.timesync_wait_s, "s",
                    "no TIMESYNC answer from the vehicle, so the link delay the controller predicts "
                    "across is unknown: set fixed_delay_s in the controller file to the vehicle's "
                    "sample-to-actuation delay, or enable TIMESYNC on the vehicle"), out, Phase.PREFLIGHT)
                return
            self._command(out, mm.arm_disarm(sysid, compid, True))
        elif not st.offboard:
            if t - self._stream_start_t >= self.params.offboard_stream_min_s:
                self._command(out, self.autopilot.set_offboard_mode())
        else:
            verdict = self.gate.link_verdict(self._gate_margin(self._pending[0][0]))
            if verdict is not None:
                self._refuse(verdict, out, Phase.PREFLIGHT)
                return
            self._start_takeoff(sample, out)

    def _start_ramps(self, ramps, t: float) -> None:
        self._ramps = list(ramps)
        self._ramp_t0 = t

    def _start_takeoff(self, sample, out) -> None:
        plan = self._pending[0][0]
        entry = fp.entry_of(plan, self.params.hover, self.params.run_in_m, self.params.entry_offset_m)
        p = sample.x[:3].copy()
        self._ground_z = float(p[2])
        self.monitor.set_origin(p)
        ramps = fp.takeoff_ramps(p, float(sample.x[5]), entry, self.params.spool_s, self.params.hover)
        self._set_phase(out, Phase.TAKEOFF, f"take-off from z={p[2]:.2f} m to hold point "
                        f"{np.round(entry.hold_m, 3).tolist()} for {plan.name!r}")
        self._start_ramps(ramps, sample.time_s)

    # ------------------------------------------------------------------ control
    def _hover_control(self, sample, x):
        t = sample.time_s - self._ramp_t0
        while len(self._ramps) > 1 and self._ramps[0].finished(t):
            self._ramp_t0 += self._ramps[0].duration_s
            t -= self._ramps[0].duration_s
            self._ramps.pop(0)
        ramp = self._ramps[0]
        return (self.hover.step(x, ramp, t, self.forecaster.disturbance),
                len(self._ramps) == 1 and ramp.finished(t))

    def _record(self, sample, s, w, u, rotors) -> LogRecord:
        """The log keeps the measured state (the controllers may act on a prediction of it)."""
        est = self.forecaster.disturbance
        dist = (math.nan,) * 6 if est is None else (*est.drag_n_s_per_m, *est.force_ned_n, est.thrust_scale)
        return LogRecord(sample.time_s, self.phase, s, np.asarray(w, float), np.asarray(u, float),
                         np.asarray(rotors, float), np.array(sample.x, dtype=float), dist)

    def _control(self, sample, x, out):
        """(rotor forces, log record, tracking errors or None) of the current phase."""
        if self.phase == Phase.MANEUVER:
            return self._maneuver_control(sample, x, out)
        if self.phase == Phase.RECOVER:
            return self._recover_control(sample, x, out)
        if self.phase == Phase.LAND and self._recovery_landing:
            rotors, record, _, _ = self._recovery_step(sample, x)
            return self._land_logic(sample, rotors, out), record, None
        t = sample.time_s
        if self.phase in (Phase.TAKEOFF, Phase.LAND):     # the observer learns clear of the ground
            floor = _OBSERVE_AFTER_LIFTOFF_M if self.phase == Phase.TAKEOFF else _OBSERVE_UNTIL_LANDING_M
            self.forecaster.observing = self._ground_z - float(x[2]) > floor
        ho, ramp_done = self._hover_control(sample, x)
        rotors = ho.rotor_forces_n
        e = ho.error
        tracking = Tracking(_norm3(e, 0), angle_between(x[3:6], x[3:6] - e[3:6]), _norm3(e, 9))
        if self.phase == Phase.TAKEOFF and t - self._phase_t0 < self.params.spool_s:
            rotors = rotors * smoothstep((t - self._phase_t0) / self.params.spool_s)
        elif self.phase == Phase.LAND:
            rotors = self._land_logic(sample, rotors, out)
            if self._spool_down_t0 is not None:
                tracking = None          # on the ground: the reference sinks on without it
        record = self._record(sample, math.nan, _NAN11, ho.u, rotors)
        if self.phase == Phase.TAKEOFF and ramp_done:
            self._set_phase(out, Phase.HOLD, "take-off complete, holding")
        elif self.phase == Phase.HOLD and ramp_done:
            self.gate.observe(t, tracking.position_error_m, tracking.attitude_error_rad, rotors)
            if t - max(self._phase_t0, self._ramp_t0 + self._ramps[0].duration_s) >= self._hold_time():
                self._leave_hold(sample, out)
        elif self.phase == Phase.RUN_IN and ramp_done:
            plan, reg = self._active
            reg.reset(x, s_guess=0.0, rotor_forces_n=self._forecast.rotor_forces_n)
            self._s = 0.0
            self._set_phase(out, Phase.MANEUVER, f"maneuver {plan.name!r} begins")
        return rotors, record, tracking

    def _maneuver_control(self, sample, x, out):
        plan, reg = self._active
        r = reg.step(x, self._forecast.rotor_forces_n, self.forecaster.disturbance)
        self._s = float(r.s)
        w = np.asarray(r.w, dtype=float)
        rotors = np.asarray(r.rotor_forces_n, dtype=float)
        record = self._record(sample, r.s, w, r.u, rotors)
        attitude_error = (float(np.linalg.norm(w[2:5])) if plan.attitude_error == "so3"   # |Log(Rbar^T R)|
                          else angle_between(x[3:6], x[3:6] - w[2:5]))
        tracking = Tracking(float(math.hypot(w[0], w[1])), attitude_error, _norm3(w, 8), self._s,
                            bool(r.in_tube))
        if r.finished and np.all(np.isfinite(rotors)):
            self._maneuvers_done.append(plan.name)
            self._active = None
            self._start_exit_hold(sample, out)
        return rotors, record, tracking

    def _recovery_step(self, sample, x):
        """(rotor forces, log record, NED velocity, R) of the recovery controller on state ``x``."""
        R = rpy_to_matrix(*x[3:6])
        v_ned = R @ x[6:9]
        o = self.recovery.step(sample.time_s, x[:3], v_ned, R, x[9:12])
        u = np.concatenate([[o.thrust_n], o.torque_n_m])
        return o.rotor_forces_n, self._record(sample, math.nan, _NAN11, u, o.rotor_forces_n), v_ned, R

    def _recover_control(self, sample, x, out):
        t = sample.time_s
        rotors, record, v_ned, R = self._recovery_step(sample, x)
        if self.recovery.settled(x[:3], v_ned, R):
            if self._settled_since is None:
                self._settled_since = t
            if t - self._settled_since >= self.envelope.recovery.settle_s:
                self._recovered(sample, x, out)
        else:
            self._settled_since = None
        return rotors, record, None

    def _recovered(self, sample, x, out) -> None:
        t = sample.time_s
        p = np.array(x[:3], dtype=float)
        yaw = float(x[5])
        self._note_action(f"recovered after {t - self._phase_t0:.1f} s")
        self._s = math.nan
        then = "landing" if self.params.land_when_done or self._land_requested else "holding"
        self._announce(out, "recovered", mm.SEVERITY_WARNING,
                       f"level and holding at {np.round(p, 2).tolist()} after {t - self._phase_t0:.1f} s; {then}")
        if self.params.land_when_done or self._land_requested:
            self._set_phase(out, Phase.LAND, f"recovered at {np.round(p, 2).tolist()}; landing")
            self._note_action("landing")
            self._start_ramps([fp.land_ramp(p, yaw, self._ground_z, self.params.land_slow_altitude_m,
                                            self.params.land_speed_m_s, self.params.hover)], t)
        else:
            self._set_phase(out, Phase.HOLD, f"recovered at {np.round(p, 2).tolist()}; holding, "
                            "waiting for an upload")
            self._note_action("holding")
            self._start_ramps([hold_ramp(p, yaw)], t)

    # ------------------------------------------------------------------ hold, gate
    def _hold_time(self) -> float:
        return self.params.hold_after_s if self._maneuvers_done else self.params.hold_before_s

    def _leave_hold(self, sample, out) -> None:
        hp = self.params.hover
        t = sample.time_s
        p = sample.x[:3]
        hold_p = self._ramps[-1].end_position_m
        hold_yaw = self._ramps[-1].end_yaw_rad
        if self._pending and not self._land_requested:
            verdict = self._gate_verdict()
            if verdict is None:
                return                                     # not a full window yet: hold on
            if not verdict.ok:
                if self._gate_wait_t0 is None:
                    self._gate_wait_t0 = t
                self._gate_last = verdict
                if t - self._gate_wait_t0 < self.envelope.gate.timeout_s:
                    return                                 # hold on: it may settle
                self._refuse(verdict, out)
                if self._pending:
                    return
            else:
                plan, reg, _ = self._pending.pop(0)
                self._gate_wait_t0 = None
                self._active = (plan, reg)
                entry = fp.entry_of(plan, hp, self.params.run_in_m, self.params.entry_offset_m)
                ramps = fp.run_in_ramps(hold_p, hold_yaw, entry, hp)
                self._s = math.nan
                self._set_phase(out, Phase.RUN_IN, f"health gate passed; run-in to the entry of "
                                f"{plan.name!r} from {np.round(p, 3).tolist()}")
                self._start_ramps(ramps, t)
                return
        if self.params.land_when_done or self._land_requested:
            ramp = fp.land_ramp(hold_p, hold_yaw, self._ground_z, self.params.land_slow_altitude_m,
                                self.params.land_speed_m_s, hp)
            self._s = math.nan
            self._set_phase(out, Phase.LAND, f"landing from {np.round(p, 3).tolist()}")
            self._start_ramps([ramp], t)

    def _gate_verdict(self):
        """The gate's verdict on the first pending plan (None: the window is not full yet)."""
        if not self.gate.ready():
            return None
        plan, _, pts = self._pending[0]
        bad = plan_outside_envelope(pts, self.monitor.origin, self.envelope)
        return bad if bad is not None else self.gate.evaluate(self._gate_margin(plan))

    def _gate_margin(self, plan) -> MarginCheck | None:
        """The delay margin the gate holds the link to (:meth:`HealthGate.link_verdict`), with the
        link delay the prediction covers; None: the plan has no margins."""
        margin = delay_margin_of(plan)
        if margin is None:
            return None
        covered = None
        if self.forecaster.predict:
            cap = self.forecaster.predictor.max_horizon_s
            covered = min(self.delay.total_s(), cap) - self.delay.vehicle_s
        return MarginCheck(*margin, covered, self.forecaster.period_s)

    def _start_exit_hold(self, sample, out) -> None:
        p = sample.x[:3]
        v = sample.velocity_ned_m_s
        ramp = fp.stop_ramp(p, v, float(sample.x[5]), self.params.hover)
        self._set_phase(out, Phase.HOLD, f"maneuver finished at {np.round(p, 3).tolist()}, "
                        f"{float(np.linalg.norm(v)):.2f} m/s; stopping and holding at the exit")
        self._start_ramps([ramp], sample.time_s)

    # ------------------------------------------------------------------ landing
    def _land_logic(self, sample, rotors: np.ndarray, out) -> np.ndarray:
        t = sample.time_s
        altitude = self._ground_z - sample.x[2]
        if self._spool_down_t0 is None:
            self._descent.append((t, float(sample.velocity_ned_m_s[2])))
            while self._descent and t - self._descent[0][0] > 0.3:
                self._descent.popleft()
            if altitude <= self.params.touchdown_altitude_m:
                self._spool_down_t0 = t
                speed = max(vz for _, vz in self._descent)
                self._touchdown_speed = speed
                self._event(out, "touchdown", f"touchdown at altitude {altitude:.3f} m, descending at "
                            f"{speed:.2f} m/s; spooling down")
                self._check_touchdown(speed, out)
            else:
                return rotors
        blend = 1.0 - smoothstep((t - self._spool_down_t0) / self.params.spool_s)
        if blend <= 0.0:
            st = self.vehicle_status
            if st is not None and st.armed:
                idle_s = t - self._spool_down_t0 - self.params.spool_s
                self._command(out, self._ground_disarm(idle_s, st))
        return rotors * blend

    def _ground_disarm(self, idle_s: float, st):
        """Touched down, motors idle for ``idle_s``: ask for a disarm; after
        ``land_mode_after_s`` (at once where the dialect says so: ArduCopter refuses a disarm in
        GUIDED until its land detector has seen the landing, which under thrust set-points it
        rarely does), ask for the autopilot's own landing mode instead, which disarms on the
        ground by itself."""
        dialect = self.autopilot.dialect
        wait_s = 0.0 if dialect.disarm_by_land_mode else self.params.land_mode_after_s
        if idle_s < wait_s or st.mode == dialect.land_mode:
            return mm.arm_disarm(self.params.vehicle_system_id, self.params.vehicle_component_id, False)
        self._land_mode_requested = True
        return self.autopilot.dialect.set_land_mode(self.params.vehicle_system_id,
                                                    self.params.vehicle_component_id)
