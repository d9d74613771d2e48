"""Supervisor phases on a deterministic fake vehicle (injected clock, no sockets)."""
import math

import numpy as np

from mavreg.daemon.flight.supervisor import Phase
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, VEHICLE, make_supervisor, run


def _phases(events):
    return [e.phase for e in events if e.kind == "phase"]


def test_full_flight_phases_in_order_and_lands_disarmed():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    events, logs, sent = run(sup, veh, 60.0)
    # each phase-change event is stamped with the phase it enters
    assert _phases(events) == [Phase.TAKEOFF, Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER,
                               Phase.HOLD, Phase.LAND, Phase.DISARMED]
    assert sup.succeeded and not veh.armed
    assert abs(veh.x[2]) < 1e-9
    # the maneuver began where the plan enters, and the regulator was reset there
    (x_reset, s_guess), = sup.regulators[0].resets
    assert s_guess == 0.0 and np.linalg.norm(x_reset[:3] - np.array(FakePlan().start)) < 0.03
    man = [r for r in logs if r.phase == Phase.MANEUVER]
    assert man and max(abs(r.w[0]) for r in man) < 0.05
    # smooth hand-overs: no rotor command ever reaches saturation, and the step between
    # consecutive commands stays small across every phase change in the air (touchdown waits
    # for the ground to stop the descent: this rigid ground stops it at once, a step)
    touchdown = next(e.time_s for e in events if e.kind == "touchdown")
    airborne = [r for r in logs if r.time_s < touchdown and r.x[2] < -0.005]
    cmds = np.array([r.rotor_cmd_n for r in airborne])
    assert cmds.max() < VEHICLE.max_rotor_thrust_n
    assert np.abs(np.diff(cmds, axis=0)).max() < 0.35
    # phase events carry time and arc length
    man_event = [e for e in events if e.kind == "phase" and e.phase == Phase.MANEUVER][0]
    assert man_event.s_m == 0.0 and man_event.time_s > 0


def test_preflight_streams_idle_then_arms_then_offboard():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    _, _, sent = run(sup, veh, 2.5)
    kinds = [(t, m.get_type(), getattr(m, "command", None)) for t, m in sent]
    first_cmd = next(k for k in kinds if k[1] == "COMMAND_LONG" and k[2] != 511)
    assert kinds[0][2] == 511                               # the telemetry asked for at the first HEARTBEAT
    assert next(k for k in kinds if k[2] != 511)[1] == "SET_ACTUATOR_CONTROL_TARGET"
    assert first_cmd[2] == 400
    # before arming: the telemetry asked for (SET_MESSAGE_INTERVAL) and the parameters read
    before = [k for k in kinds if k[0] < first_cmd[0]]
    assert {k[2] for k in before if k[1] == "COMMAND_LONG"} == {511}
    assert sum(k[1] == "PARAM_REQUEST_READ" for k in before) == 2
    mode_cmds = [k for k in kinds if k[2] == 176]
    assert mode_cmds and mode_cmds[0][0] >= 700  # after >= 0.7 s of streaming (vehicle time)
    idle = [m for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and t < mode_cmds[0][0]]
    assert all(max(m.controls) == 0.0 for m in idle)
    assert sup.phase == Phase.TAKEOFF


def test_a_parameter_that_does_not_hold_refuses_take_off_in_one_line():
    """PX4's offboard-loss action at Terminate (6) would stop the motors in the air: refused
    on the ground, the line names the parameter and the value to set; never armed."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(params={"COM_OF_LOSS_T": 0.5, "COM_OBL_RC_ACT": 6.0})
    _, events, _ = run(sup, veh, 3.0)
    assert not veh.armed and sup.failure is not None and sup.failure.bound == "gate_parameter"
    assert "COM_OBL_RC_ACT is 6" in sup.failure.detail and "set 5" in sup.failure.detail
    assert "\n" not in sup.failure.line()


def test_unanswered_parameter_reads_refuse_after_the_timeout():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(params={"COM_OF_LOSS_T": 0.5})          # COM_OBL_RC_ACT never answered
    _, _, sent = run(sup, veh, 12.0)
    assert not veh.armed and sup.failure.bound == "gate_parameter"
    assert "COM_OBL_RC_ACT" in sup.failure.detail and "did not answer" in sup.failure.detail
    reads = [m for _, m in sent if m.get_type() == "PARAM_REQUEST_READ"]
    assert 8 <= len(reads) <= 14                            # the missing one, about once a second


def test_custom_firmware_that_announces_generic_flies_with_px4_modes_and_says_so():
    """MAV_AUTOPILOT_GENERIC in the rotors output: PX4's mode layout by default, announced in
    one line naming the option that changes it; no parameter is read (the rules name PX4's)."""
    from tests.helpers.supervisor_harness import mavlink2 as m2
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(autopilot=m2.MAV_AUTOPILOT_GENERIC)
    events, _, sent = run(sup, veh, 60.0)
    assert sup.succeeded and not veh.armed
    (notice,) = [e for e in events if e.kind == "dialect"]
    assert "PX4's mode layout" in notice.detail and "--dialect px4|ardupilot" in notice.detail
    assert "\n" not in notice.detail and sup.autopilot.dialect.rules == ()
    assert not any(m.get_type() == "PARAM_REQUEST_READ" for _, m in sent)


def test_without_a_plan_it_streams_idle_but_never_arms():
    sup = make_supervisor(None)
    veh = SimVehicle()
    _, _, sent = run(sup, veh, 2.0)
    assert not any(m.get_type() == "COMMAND_LONG" and m.command != 511 for _, m in sent)  # telemetry asks only
    assert sup.phase == Phase.PREFLIGHT and not veh.armed


def test_no_message_before_vehicle_heartbeat():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    for m in veh.telemetry():
        assert sup.handle(m, 0.0).messages == []


def test_vehicle_leaving_offboard_aborts_and_stops_stream():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 4.0)
    assert sup.phase == Phase.TAKEOFF
    veh.main, veh.sub = 4, 3   # vehicle failsafe to HOLD
    sup.handle(veh.heartbeat(), veh.t_ms / 1000)
    assert sup.phase == Phase.ABORTED and "OFFBOARD" in sup.reason
    for m in veh.telemetry():
        veh.t_ms += 4
        assert sup.handle(m, veh.t_ms / 1000).messages == []
    assert not sup.succeeded


def test_land_request_in_serve_mode():
    sup = make_supervisor(FakePlan(), land_when_done=False)
    veh = SimVehicle()
    run(sup, veh, 25.0)
    assert sup.phase == Phase.HOLD and sup.status()["done"] == ["line"]
    sup.request_land(veh.t_ms / 1000)
    events, _, _ = run(sup, veh, 20.0)
    assert _phases(events) == [Phase.LAND, Phase.DISARMED]


def test_events_format_with_time_and_arc_length():
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    events, _, _ = run(sup, veh, 15.0)
    lines = [e.line() for e in events]
    assert any("maneuver" in ln and "s=0.000 m" in ln for ln in lines)
    assert all(not math.isnan(e.time_s) for e in events if e.kind == "phase")


def test_harness_vehicle_sits_still_when_disarmed():
    """The harness's vehicle (tests/helpers/supervisor_harness.py) does not move unarmed."""
    veh = SimVehicle()
    for _ in range(10):
        veh.physics()
    assert np.all(veh.x == 0.0)


def test_gains_that_oscillate_between_commands_are_refused_before_take_off():
    """A regulator whose feedback on the achieved wrench answers more than its share of each
    command within one control period (lag_loop_factor above the gate's bound) does not take
    off; one line says why and what to change."""
    from mavreg.daemon.flight.gate import MAX_LAG_LOOP_FACTOR
    from tests.helpers.supervisor_harness import FakeRegulator
    plan = FakePlan()
    reg = FakeRegulator(plan)
    reg.lag_loop_factor = MAX_LAG_LOOP_FACTOR + 0.5
    sup = make_supervisor(plan, regulator=reg)
    veh = SimVehicle()
    run(sup, veh, 3.0)
    assert not veh.armed and sup.failure.bound == "gate_control_period"
    assert "rotor_time_constant_s" in sup.failure.detail and len(sup.failure.line().splitlines()) == 1
