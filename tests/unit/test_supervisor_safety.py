"""The supervisor's safety actions on the fake vehicle of tests/helpers/supervisor_harness.py (design
model RK4, injected clock = vehicle time, no sockets): recover, stop the motors, hand
over, refuse at the gate, gaps, the honest outcome."""
from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.envelope import EnvelopeParams
from mavreg.daemon.flight.phases import Phase
from mavreg.model.rotation import rpy_to_quat, rpy_to_matrix
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run, wire


def _kinds(events):
    return [e.kind for e in events]


def _phases(events):
    return [e.phase for e in events if e.kind == "phase"]


def _actuators(sent, after_ms=-1):
    return [m for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and t > after_ms]


def _texts(sent):
    """(severity, text) of the STATUSTEXTs sent, chunked ones reassembled."""
    out, chunks = [], {}
    for _, m in sent:
        if m.get_type() != "STATUSTEXT":
            continue
        text = m.text.decode() if isinstance(m.text, bytes) else m.text
        if m.id == 0:
            out.append((m.severity, text))
        else:
            chunks.setdefault(m.id, (m.severity, []))[1].append(text)
            if len(text) < 50:
                out.append((m.severity, "".join(chunks.pop(m.id)[1])))
    return out


def gust(sup, start, axis, accel_m_s2, duration_s):
    """on_step hook: a body-axis acceleration (a force gust) for ``duration_s`` from the
    first step where ``start(sup)`` holds. (A velocity step would be an impact.)"""
    state = {}

    def hook(v, msgs):
        if "t" not in state and start(sup):
            state["t"] = v.t_ms
        if "t" in state and v.t_ms - state["t"] < 1000 * duration_s:
            v.x[6 + axis] += accel_m_s2 * v.dt
        return msgs
    return state, hook


def in_maneuver(sup):
    return sup.phase == Phase.MANEUVER and sup.ctx.s_m > 1.0 and sup.ctx.recovery.count == 0


def test_push_off_the_path_recovers_then_lands():
    """A sideways gust (3 m/s^2 for 3 s) in the maneuver: the path-distance bound fires,
    the recovery controller brakes and holds, then the vehicle lands; the flight is failed."""
    sup = make_supervisor(FakePlan(length_m=3.0))
    veh = SimVehicle()
    pushed, shove = gust(sup, in_maneuver, 1, 3.0, 3.0)
    events, logs, sent = run(sup, veh, 60.0, shove)
    assert pushed
    assert _phases(events)[-3:] == [Phase.RECOVER, Phase.LAND, Phase.DISARMED]
    f = sup.failure
    assert f.bound == "position_error" and f.phase == Phase.MANEUVER and f.value > 0.5 and f.limit == 0.5
    assert 1.0 < f.s_m < 3.0 and f.action.startswith("recovery, then recovered")
    assert "landing" in f.action
    assert not sup.succeeded and not veh.armed and abs(veh.x[2]) < 1e-9
    # announced: a CRITICAL STATUSTEXT naming the bound
    crit = [t for sev, t in _texts(sent) if sev == mavlink2.MAV_SEVERITY_CRITICAL]
    assert any("recover" in t and "position_error" in t for t in crit)
    # the recovery stopped the drift within a couple of metres of where it was pushed
    rec = np.array([r.x[:3] for r in logs if r.phase == Phase.RECOVER])
    assert np.ptp(rec[:, 1]) < 2.0
    assert sup.status()["failure"]["bound"] == "position_error"


def test_pushed_down_harder_than_the_rotors_can_hold_stops_the_motors_only_at_the_ground():
    """Pushed down at 60 m/s^2 (more than the rotors' 64 m/s^2 minus g) from the 2 m hold: a
    tracking bound starts a recovery; its full thrust does not show in the measured
    acceleration (thrust mismatch) but that, in the air, only lets the recovery go on. The
    ground comes: the impact stops the motors by a forced disarm, there and not before, and
    not one rotor command is sent after it."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    _, throw = gust(sup, lambda s: s.phase == Phase.HOLD, 2, 60.0, 0.4)
    events, logs, sent = run(sup, veh, 30.0, throw)
    assert [e.kind for e in events if e.kind in ("recover", "motors_stopped")] == ["recover", "motors_stopped"]
    stop = next(e for e in events if e.kind == "motors_stopped")
    assert "impact" in stop.detail
    altitude = float(re.search(r"at (-?[0-9.]+) m above the take-off point", stop.detail).group(1))
    assert altitude <= EnvelopeParams().impact_altitude_m           # at the ground, not in the air
    assert min(-r.x[2] for r in logs if r.phase == Phase.RECOVER) > altitude
    assert sup.phase == Phase.DISARMED and not veh.armed
    assert sup.failure.phase == Phase.HOLD
    assert "motors stopped (forced disarm)" in sup.failure.action
    stop_ms = round(stop.time_s * 1000)
    assert _actuators(sent, after_ms=stop_ms) == []        # no thrust after it
    forced = [m for t, m in sent if m.get_type() == "COMMAND_LONG" and t >= stop_ms]
    assert forced and all(m.command == 400 and m.param1 == 0 and m.param2 == 21196 for m in forced)
    crit = [t for sev, t in _texts(sent) if sev == mavlink2.MAV_SEVERITY_CRITICAL]
    assert any("motors_stopped" in t and "forced disarm" in t for t in crit)


def test_impact_at_the_ground_is_not_a_recovery():
    """Descending at 3 m/s through 0.2 m while landing: the impact bound stops the motors."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()

    _, slam = gust(sup, lambda s: s.phase == Phase.LAND and -s.last_sample.x[2] < 0.5, 2, 30.0, 1.0)
    events, _, sent = run(sup, veh, 60.0, slam)
    assert "recover" not in _kinds(events)
    assert sup.failure.bound == "impact" and sup.failure.value > 1.5 and sup.phase == Phase.DISARMED


def test_forced_disarm_repeats_until_the_vehicle_obeys():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(ignore_disarm=3)                      # the first three are lost
    _, slam = gust(sup, lambda s: s.phase == Phase.LAND and -s.last_sample.x[2] < 0.5, 2, 30.0, 1.0)
    _, _, sent = run(sup, veh, 60.0, slam)
    forced = [t for t, m in sent if m.get_type() == "COMMAND_LONG" and m.param2 == 21196]
    assert len(forced) == 4 and sup.phase == Phase.DISARMED
    gaps = np.diff(forced)
    assert np.all(gaps >= 100) and np.all(gaps <= 108)       # every disarm_retry_s (0.1 s)


def test_a_recovery_that_does_not_settle_in_time_lands_with_the_recovery_controller():
    """A recovery given 0.3 s to settle (it needs more): not a forced disarm in the air but a
    landing where it is, by the recovery controller, at the landing speed; touchdown,
    spool-down and disarm as in any landing. Rotor commands go out all the way down."""
    env = EnvelopeParams(recovery=replace(EnvelopeParams().recovery, timeout_s=0.3))
    sup = make_supervisor(FakePlan(length_m=3.0), envelope=env)
    veh = SimVehicle()
    _, shove = gust(sup, in_maneuver, 1, 3.0, 3.0)
    landing_status = []

    def hook(v, msgs):
        if sup.ctx.recovery.landing and sup.phase == Phase.LAND:
            landing_status.append(sup.heartbeat().system_status)   # the daemon says it is in trouble
        return shove(v, msgs)
    events, logs, sent = run(sup, veh, 60.0, hook)
    assert "motors_stopped" not in _kinds(events)
    assert landing_status and set(landing_status) == {mavlink2.MAV_STATE_CRITICAL}
    land = next(e for e in events if e.kind == "recovery_land")
    assert "recovery not settled" in land.detail and "recovery_timeout" in land.detail
    assert _phases(events)[-2:] == [Phase.LAND, Phase.DISARMED]
    assert sup.failure.bound == "position_error" and "landing (recovery controller)" in sup.failure.action
    assert sup.ctx.landing.touchdown_speed_m_s is not None and sup.ctx.landing.touchdown_speed_m_s < 0.5
    assert not veh.armed and abs(veh.x[2]) < 1e-9
    down = np.array([r.x[2] for r in logs if r.phase == Phase.LAND])
    assert down.min() < -1.0 and len(_actuators(sent, after_ms=round(land.time_s * 1000))) > 500


def test_gate_refuses_a_heavier_vehicle_and_lands():
    """40 % heavier than the design: the hold needs 1.4 x the hover thrust; the maneuver is
    refused with that reason, the vehicle lands."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(mass_scale=1.4)
    events, _, sent = run(sup, veh, 60.0)
    assert Phase.MANEUVER not in _phases(events) and Phase.RUN_IN not in _phases(events)
    assert _phases(events)[-2:] == [Phase.LAND, Phase.DISARMED]
    f = sup.failure
    assert f.bound == "gate_thrust" and 1.35 < f.value < 1.45 and f.phase == Phase.HOLD
    assert f.action.startswith("maneuver refused, landing")
    assert not sup.succeeded
    warn = [t for sev, t in _texts(sent) if sev == mavlink2.MAV_SEVERITY_WARNING]
    assert any("refused" in t and "gate_thrust" in t for t in warn)
    # it waited for the gate's timeout before refusing
    hold_t = next(e.time_s for e in events if e.kind == "phase" and e.phase == Phase.HOLD)
    refused_t = next(e.time_s for e in events if e.kind == "refused")
    assert refused_t - hold_t >= EnvelopeParams().gate.timeout_s


def test_gate_refuses_a_slow_link_and_an_unknown_link_does_not_block():
    sup = make_supervisor(FakePlan(), link_health=lambda: (0.08, 0.002))
    events, _, _ = run(sup, SimVehicle(), 60.0)
    assert sup.failure.bound == "gate_link_delay" and Phase.MANEUVER not in _phases(events)
    sup = make_supervisor(FakePlan(), link_health=lambda: None)
    events, _, _ = run(sup, SimVehicle(), 60.0)
    assert sup.succeeded and any("health gate passed" in e.detail for e in events)


def test_hover_rides_out_a_300_ms_telemetry_pause():
    """A busy host: nothing for 0.3 s in the hold (the vehicle holds its last command)."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    pause = {}

    def hush(v, msgs):
        if sup.phase == Phase.HOLD and "t" not in pause:
            pause["t"] = v.t_ms
        if "t" in pause and pause["t"] < v.t_ms <= pause["t"] + 300:
            return []
        return msgs
    events, _, _ = run(sup, veh, 60.0, hush)
    assert sup.succeeded, [e.line() for e in events][-5:]
    gap = next(e for e in events if e.kind == "gap")
    assert "304 ms" in gap.detail and sup.counters.gaps == 1


def test_a_gap_in_the_maneuver_starts_a_recovery():
    sup = make_supervisor(FakePlan(length_m=3.0))
    veh = SimVehicle()
    pause = {}

    def hush(v, msgs):
        if sup.phase == Phase.MANEUVER and sup.ctx.s_m > 1.0 and "t" not in pause:
            pause["t"] = v.t_ms
        if "t" in pause and pause["t"] < v.t_ms <= pause["t"] + 150:
            return []
        return msgs
    events, _, _ = run(sup, veh, 60.0, hush)
    assert sup.failure.bound == "telemetry_gap" and sup.failure.phase == Phase.MANEUVER
    assert 0.15 <= sup.failure.value < 0.16
    assert _phases(events)[-3:] == [Phase.RECOVER, Phase.LAND, Phase.DISARMED]


def test_link_lost_for_half_a_second_hands_over_to_the_vehicle():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    pause = {}

    def hush(v, msgs):
        if sup.phase == Phase.HOLD and "t" not in pause:
            pause["t"] = v.t_ms
        return [] if "t" in pause else msgs
    events, _, sent = run(sup, veh, 30.0, hush)
    assert sup.phase == Phase.ABORTED and sup.failure.bound == "link_lost"
    assert "vehicle failsafe" in sup.failure.action
    last = max(t for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET")
    assert last <= pause["t"]


def test_hard_landing_fails_the_flight():
    """Landing sinking at 1.2 m/s: under the impact bound (1.5 m/s), over the touchdown
    bound (1 m/s): landed and disarmed, but not a landing."""
    sup = make_supervisor(FakePlan(), land_speed_m_s=1.2)
    events, _, _ = run(sup, SimVehicle(), 60.0)
    assert sup.phase == Phase.DISARMED and not sup.succeeded
    assert sup.failure.bound == "touchdown_speed" and 1.0 < sup.failure.value < 1.3
    assert "impact" not in sup.failure.action and "motors stopped" not in sup.failure.action


def test_serve_recovers_then_holds_and_waits_for_an_upload():
    sup = make_supervisor(FakePlan(length_m=3.0), land_when_done=False)
    veh = SimVehicle()
    _, shove = gust(sup, in_maneuver, 1, 3.0, 3.0)
    events, _, _ = run(sup, veh, 20.0, shove)
    assert sup.phase == Phase.HOLD and sup.ctx.recovery.count == 1 and veh.armed
    assert sup.failure.action.endswith("holding")
    # a new upload is flown from there (after the gate)
    sup.offer_plan(FakePlan(name="again", start=(veh.x[0] + 1.0, veh.x[1], -2.5)), veh.t_ms / 1000)
    events, _, _ = run(sup, veh, 30.0)
    assert Phase.MANEUVER in _phases(events) and "again" in sup.status()["done"]


class RealisticVehicle(SimVehicle):
    """The fake vehicle seen through an estimator and a link: Gauss-Markov errors of the
    emulator's realistic world (position 5 mm / 0.5 s, velocity 2 cm/s / 0.2 s, attitude
    0.3 deg / 0.5 s, gyro noise 0.005 rad/s), telemetry 12 ms late, commands 4 ms late,
    1 % of the messages lost."""

    def __init__(self, seed=0):
        super().__init__()
        self.rng = np.random.default_rng(seed)
        self.err = np.zeros(9)            # position, velocity, attitude
        self.sd = np.array([0.005] * 3 + [0.02] * 3 + [math.radians(0.3)] * 3)
        self.a = np.exp(-self.dt / np.array([0.5] * 3 + [0.2] * 3 + [0.5] * 3))
        self.tm_queue, self.cmd_queue = [], []

    def telemetry(self):
        self.err = self.a * self.err + np.sqrt(1 - self.a ** 2) * self.sd * self.rng.standard_normal(9)
        rpy = self.x[3:6] + self.err[6:9]
        q = rpy_to_quat(*rpy)
        v_ned = rpy_to_matrix(*self.x[3:6]) @ self.x[6:9] + self.err[3:6]
        r = self.x[9:12] + self.rng.normal(0, 0.005, 3)
        msgs = [wire(mavlink2.MAVLink_attitude_quaternion_message(self.t_ms, *q, *r)),
                wire(mavlink2.MAVLink_local_position_ned_message(self.t_ms, *(self.x[:3] + self.err[:3]), *v_ned))]
        msgs = [m for m in msgs if self.rng.random() > 0.01]
        self.tm_queue.append((self.t_ms + 12, msgs))
        out = [m for due, ms in self.tm_queue if due <= self.t_ms for m in ms]
        self.tm_queue = [(due, ms) for due, ms in self.tm_queue if due > self.t_ms]
        return out

    def receive(self, msg):
        self.cmd_queue.append((self.t_ms + 4, msg))

    def physics(self):
        due = [m for t, m in self.cmd_queue if t <= self.t_ms]
        self.cmd_queue = [(t, m) for t, m in self.cmd_queue if t > self.t_ms]
        for m in due:
            SimVehicle.receive(self, m)
        super().physics()


def test_a_clean_flight_through_an_estimator_and_a_link_fires_nothing():
    sup = make_supervisor(FakePlan(length_m=3.0))
    veh = RealisticVehicle()
    events, _, _ = run(sup, veh, 60.0)
    assert sup.succeeded, [e.line() for e in events][-6:]
    peaks = sup.status()["envelope_peaks"]
    assert all(p["unit"] for p in peaks.values())              # summary.json names each value's unit
    assert peaks["body_rate"]["unit"] == "rad/s" and peaks["attitude_error.maneuver"]["unit"] == "rad"
    where = {"altitude_floor", "geofence"}       # where the plan is, not how well it is flown
    worst = max(((k, v) for k, v in peaks.items() if k not in where), key=lambda kv: kv[1]["ratio"])
    print(f"\nestimator + link: closest bound {worst[0]} at {100 * worst[1]['ratio']:.0f} % of its limit")
    assert worst[1]["ratio"] < 0.5
    assert peaks["altitude_floor"]["ratio"] < 0.55                 # the plan flies at 2 m, floor 1 m


def test_a_vehicle_that_never_answers_timesync_is_refused_take_off_in_one_line():
    """No TIMESYNC answer and no configured delay: the link delay the controller predicts
    across is unknown. The daemon waits ``timesync_wait_s`` of vehicle time, then refuses
    before arming, names fixed_delay_s, and the vehicle never leaves the ground."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(answer_timesync=False)
    events, logs, sent = run(sup, veh, 10.0)
    assert sup.phase == Phase.DISARMED and sup.failure.bound == "gate_no_timesync"
    assert sup.failure.phase == Phase.PREFLIGHT and "fixed_delay_s" in sup.failure.detail
    assert not any(m.get_type() == "COMMAND_LONG" and m.command == 400 and m.param1 == 1.0 for _, m in sent)
    assert Phase.TAKEOFF not in _phases(events) and veh.x[2] == 0.0
    assert 2.0 <= sup.failure.value < 2.1                          # waited timesync_wait_s, no longer
    assert len(sup.failure.line().splitlines()) == 1


def test_a_configured_delay_flies_a_vehicle_without_timesync():
    """The same vehicle with fixed_delay_s set: nothing to wait for, the flight is flown."""
    sup = make_supervisor(FakePlan())
    sup.delay.fixed_delay_s = 0.004
    veh = SimVehicle(answer_timesync=False)
    run(sup, veh, 60.0)
    assert sup.succeeded, sup.failure


def test_a_plan_outside_the_geofence_is_refused_before_take_off():
    """The geofence ceiling below the plan: refused on the ground (not after a long climb)."""
    env = replace(EnvelopeParams(), geofence_ceiling_m=1.0)
    sup = make_supervisor(FakePlan(), envelope=env)
    veh = SimVehicle()
    events, _, sent = run(sup, veh, 10.0)
    assert sup.failure.bound == "gate_plan_geofence" and sup.failure.phase == Phase.PREFLIGHT
    assert Phase.TAKEOFF not in _phases(events) and not veh.armed
