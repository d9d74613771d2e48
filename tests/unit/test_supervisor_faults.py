"""Supervisor faults: stale state, mixed times, foreign ids, non-finite output, uploads."""
import numpy as np

from mavreg.daemon.flight.supervisor import Phase
from tests.helpers.supervisor_harness import att_q, pos
from tests.helpers.supervisor_harness import FakePlan, FakeRegulator, SimVehicle, make_supervisor, run, wire
from pymavlink.dialects.v20 import common as mavlink2


def _text(m) -> str:
    return m.text.decode(errors="replace").rstrip("\x00") if isinstance(m.text, bytes) else m.text


def _actuators(out):
    return [m for m in out.messages if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET"]


def test_stale_state_stops_stream_for_good():
    sup = make_supervisor(FakePlan(), stale_timeout_s=0.1)
    veh = SimVehicle()
    run(sup, veh, 5.0)
    assert sup.phase == Phase.TAKEOFF
    now = veh.t_ms / 1000
    for k in range(1, 5):                                # ticks every 20 ms: still fresh
        assert sup.tick(now + 0.02 * k).events == []
    for k in range(5, 10):
        out = sup.tick(now + 0.02 * k)
        if out.events:
            break
    assert sup.phase == Phase.ABORTED and "stale" in sup.reason
    assert any(e.phase == Phase.ABORTED for e in out.events) and _actuators(out) == []
    # announced to the vehicle (and the .tlog) as a CRITICAL STATUSTEXT, beside the phase change
    # itself (INFO, for the autopilot's own log)
    texts = [m for m in out.messages if m.get_type() == "STATUSTEXT"]
    phase = [m for m in texts if m.severity == mavlink2.MAV_SEVERITY_INFO]
    assert phase and _text(phase[0]).startswith("mavreg phase: aborted: stale")
    cause = [m for m in texts if m not in phase]
    assert cause and all(m.severity == mavlink2.MAV_SEVERITY_CRITICAL for m in cause)
    assert sup.failure.bound == "link_lost" and sup.failure.value > 0.1
    assert 0.1 < 0.02 * k + veh.dt <= 0.13   # the last sample came one period before `now`
    # fresh samples afterwards never restart the stream
    sent = 0
    for k in range(20):
        veh.t_ms += 4
        for m in veh.telemetry():
            sent += len(_actuators(sup.handle(m, now + 0.3 + k * 0.004)))
        sup.tick(now + 0.3 + k * 0.004)
    assert sent == 0


def test_a_stalled_process_is_not_mistaken_for_a_stale_link():
    sup = make_supervisor(FakePlan(), stale_timeout_s=0.1)
    veh = SimVehicle()
    run(sup, veh, 5.0)
    now = veh.t_ms / 1000
    sup.tick(now)
    assert sup.tick(now + 0.5).events == []     # the loop itself was late: not judged
    assert sup.phase == Phase.TAKEOFF
    assert sup.tick(now + 0.52).events != []    # a running loop that still sees nothing: stale
    assert sup.phase == Phase.ABORTED


def test_no_command_without_a_complete_sample():
    """Half samples (attitude only) produce nothing: commands are never re-sent blindly."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 4.0)
    quiet = 0
    for k in range(10):
        veh.t_ms += 4
        quiet += len(_actuators(sup.handle(veh.telemetry()[0], veh.t_ms / 1000)))
    assert quiet == 0


def test_mixed_time_parts_never_make_a_command():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 4.0)
    n0 = sup.counters.samples
    t = veh.t_ms
    msgs = [att_q(t + 4), pos(t + 8), att_q(t + 12), pos(t + 16)]
    assert all(_actuators(sup.handle(m, t / 1000)) == [] for m in msgs)
    assert sup.counters.samples == n0


def test_foreign_ids_dropped_and_counted():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 4.0)
    before = sup.status()
    x_before = sup.last_sample.x.copy()
    t = veh.t_ms + 4
    foreign = [
        wire(mavlink2.MAVLink_heartbeat_message(2, 0, 0, 0, 4, 3), sysid=42),            # disarmed?
        wire(mavlink2.MAVLink_attitude_quaternion_message(t, 0, 1, 0, 0, 0, 0, 0), sysid=42),
        wire(mavlink2.MAVLink_local_position_ned_message(t, 50, 50, 50, 0, 0, 0), sysid=42),
        wire(mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, [1.0] * 8), sysid=42),
        wire(mavlink2.MAVLink_local_position_ned_message(t, 50, 50, 50, 0, 0, 0), sysid=1, compid=7),
    ]
    for m in foreign:
        out = sup.handle(m, t / 1000)
        assert out.messages == [] and out.events == []
    assert sup.counters.foreign_dropped == 5
    assert sup.phase == before["phase"] and np.array_equal(sup.last_sample.x, x_before)


def test_non_finite_controller_output_stops_streaming():
    plan = FakePlan()
    sup = make_supervisor(plan, regulator=FakeRegulator(plan, nan_at_s=0.5))
    veh = SimVehicle()
    events, _, sent = run(sup, veh, 30.0)
    assert sup.phase == Phase.ABORTED and "non-finite" in sup.reason
    assert sup.counters.non_finite == 1
    last = [m for _, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET"][-1]
    assert all(np.isfinite(last.controls))
    n = len(sent)
    for k in range(5):
        veh.t_ms += 4
        for m in veh.telemetry():
            assert sup.handle(m, veh.t_ms / 1000).messages == []
    assert len(sent) == n


def test_upload_mid_maneuver_waits_for_safe_point():
    sup = make_supervisor(FakePlan(name="first"), land_when_done=False)
    veh = SimVehicle()
    started = {}

    def on_step(v, msgs):
        if sup.phase == Phase.MANEUVER and "t" not in started:
            started["t"] = v.t_ms
            assert not sup.at_safe_point()
            sup.offer_plan(FakePlan(name="second", start=(4.0, 0.5, -2.5)), v.t_ms / 1000)
            started["active"] = sup.status()["active"]
        return msgs

    events, _, _ = run(sup, veh, 45.0, on_step)
    assert started["active"] == "first"
    begins = [e for e in events if e.kind == "phase" and e.phase == Phase.MANEUVER]
    assert [b.detail.split("'")[1] for b in begins] == ["first", "second"]
    # the second began only after a hold that followed the first
    phases = [e.phase for e in events if e.kind == "phase"]
    i = phases.index(Phase.MANEUVER)
    assert phases[i + 1] == Phase.HOLD and Phase.RUN_IN in phases[i + 1:]
    assert sup.status()["done"] == ["first", "second"] and sup.phase == Phase.HOLD


def test_offer_after_flight_over_is_refused():
    sup = make_supervisor(FakePlan())
    sup.ctx.phase = Phase.ABORTED
    try:
        sup.offer_plan(FakePlan(), 0.0)
    except ValueError as exc:
        assert "over" in str(exc)
    else:
        raise AssertionError("expected ValueError")


def test_land_request_before_takeoff_ends_on_the_ground():
    sup = make_supervisor(None)
    veh = SimVehicle()
    run(sup, veh, 1.0)
    sup.request_land(1.0)
    assert sup.phase == Phase.DISARMED and not sup.succeeded


def test_rejected_upload_changes_nothing_accepted_waits_for_safe_point():
    import asyncio

    from mavreg.daemon.jobs.app import Daemon, DaemonConfig
    from mavreg.daemon.jobs.planner_pool import PlanResult
    from mavreg.daemon.flight.supervisor import SupervisorParams
    from tests.helpers.supervisor_harness import CONTROLLER, VEHICLE

    class FakePool:
        busy = 0

        async def plan(self, text, source):
            return PlanResult(None, f"{source}:3: segments: bad") if "bad" in text else PlanResult(FakePlan(name="second"))

    cfg = DaemonConfig("udpout:127.0.0.1:1", CONTROLLER, None, None,
                       SupervisorParams(land_when_done=False))
    d = Daemon(cfg, VEHICLE, FakeRegulator, log=lambda line: None)
    d.pool = FakePool()
    sup = d.supervisor
    sup.offer_plan(FakePlan(name="first"), 0.0)
    veh = SimVehicle()
    run(sup, veh, 13.0)
    assert sup.phase == Phase.MANEUVER
    before = (sup.status(), sup.last_sample.x.copy())
    r = asyncio.run(d.offer_text("bad", "x.yaml"))
    assert r == {"ok": False, "verdict": "rejected", "reason": "x.yaml:3: segments: bad"}
    after = sup.status()
    assert after == before[0] and d.uploads == {"accepted": 0, "rejected": 1}
    r = asyncio.run(d.offer_text("good", "y.yaml"))
    assert r["ok"] and "next safe point" in r["detail"]
    assert sup.status()["active"] == "first" and sup.status()["pending"] == ["second"]
