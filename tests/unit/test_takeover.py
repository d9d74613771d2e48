"""A vehicle found armed in the air (a daemon restarted after a crash, mid-flight, while the
autopilot's failsafe holds): the supervisor takes it over without arming, disarming or taking
off, with set-points that match it before OFFBOARD, then holds and lands it or flies the
queued maneuver (``airborne``). On the fake vehicle of tests/helpers/supervisor_harness.py,
whose autopilot holds its state perfectly until OFFBOARD is granted."""
from __future__ import annotations

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.flight.phases import Phase
from tests.helpers.supervisor_harness import VEHICLE, FakePlan, SimVehicle, make_supervisor, run, wire

HOVER_CONTROL = VEHICLE.mass_kg * 9.81 / 4 / VEHICLE.max_rotor_thrust_n


def _airborne(height_m=4.0, armed=True):
    veh = SimVehicle()
    veh.x[2] = -height_m
    veh.armed = armed
    return veh


def _commands(sent, command):
    return [(t, m) for t, m in sent if m.get_type() == "COMMAND_LONG" and m.command == command]


def _phases(events):
    return [e.phase for e in events if e.kind == "phase"]


def _landed_state(state):
    def hook(veh, msgs):
        return msgs + [wire(mavlink2.MAVLink_extended_sys_state_message(0, state), sysid=veh.system_id)]
    return hook


def test_an_airborne_vehicle_is_taken_over_with_matching_set_points_and_landed():
    veh = _airborne(4.0)
    sup = make_supervisor(FakePlan())
    events, _, sent = run(sup, veh, 40.0)
    phases = _phases(events)
    assert phases[:3] == [Phase.TAKEOVER, Phase.RECOVER, Phase.LAND], phases
    assert phases[-1] == Phase.DISARMED
    arms = [m for _, m in _commands(sent, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM)]
    assert not any(m.param1 == 1.0 for m in arms)                  # never armed
    assert sup.ctx.landing.touchdown_speed_m_s is not None and sup.ctx.landing.touchdown_speed_m_s < 1.0
    first_disarm = min(t for t, m in _commands(sent, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM))
    touchdown = [e for e in events if e.kind == "touchdown"][0]
    assert first_disarm / 1000 >= touchdown.time_s                     # no disarm before the ground
    # before OFFBOARD was asked for, the stream held the vehicle up: about its hover thrust
    mode_t = min(t for t, _ in _commands(sent, mavlink2.MAV_CMD_DO_SET_MODE))
    before = [m.controls[:4] for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and t < mode_t]
    assert len(before) > 100
    assert np.allclose(np.mean(before, axis=1), HOVER_CONTROL, rtol=0.1)
    assert sup.ctx.pending == [] and sup.ctx.maneuvers_done == []  # the queued maneuver dropped
    # negative control: the same vehicle on the ground arms and takes off as ever
    veh2 = SimVehicle()
    events2, _, sent2 = run(make_supervisor(FakePlan()), veh2, 3.0)
    assert Phase.TAKEOVER not in _phases(events2)
    assert any(m.param1 == 1.0 for _, m in _commands(sent2, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM))


def test_airborne_fly_flies_the_queued_maneuver_from_the_hold():
    veh = _airborne(4.0)
    sup = make_supervisor(FakePlan(), airborne="fly")
    events, _, sent = run(sup, veh, 60.0)
    phases = _phases(events)
    assert phases[:3] == [Phase.TAKEOVER, Phase.RECOVER, Phase.HOLD], phases
    assert Phase.MANEUVER in phases and phases[-1] == Phase.DISARMED
    assert sup.ctx.maneuvers_done == ["line"]
    assert not any(m.param1 == 1.0 for _, m in _commands(sent, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM))


def test_armed_on_the_ground_by_another_is_refused_and_never_armed_or_flown():
    """On the ground by its landed state: refused, never armed or switched to OFFBOARD, and
    disarmed as any refusal on the ground is; by the height rule alone (no landed state) it
    may be flying after all: left armed."""
    veh = _airborne(0.0)
    sup = make_supervisor(FakePlan())
    events, _, sent = run(sup, veh, 5.0, on_step=_landed_state(mavlink2.MAV_LANDED_STATE_ON_GROUND))
    assert sup.finished and not sup.succeeded
    assert Phase.TAKEOVER not in _phases(events)
    arms = [m for _, m in _commands(sent, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM)]
    assert arms and all(m.param1 == 0.0 for m in arms) and not veh.armed   # disarmed, never armed
    assert _commands(sent, mavlink2.MAV_CMD_DO_SET_MODE) == []
    assert sup.failure.bound == "armed_by_another"
    veh = _airborne(0.2)
    sup = make_supervisor(FakePlan())
    _, _, sent = run(sup, veh, 5.0)
    assert sup.finished and sup.failure.bound == "armed_by_another"
    assert _commands(sent, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM) == [] and veh.armed


def test_the_landed_state_decides_before_the_height():
    """An autopilot that says it is in the air is taken over at once (no wait for the height
    rule), even low; one that never says is judged by its height after the wait."""
    veh = _airborne(0.3)
    sup = make_supervisor(FakePlan())
    events, _, _ = run(sup, veh, 2.5, on_step=_landed_state(mavlink2.MAV_LANDED_STATE_IN_AIR))
    assert Phase.TAKEOVER in _phases(events)
    veh = _airborne(0.3)
    sup = make_supervisor(FakePlan())
    run(sup, veh, 2.5)                            # no landed state, 0.3 m: on the ground
    assert sup.finished and sup.failure.bound == "armed_by_another"


def test_a_vehicle_that_disarms_during_the_takeover_is_on_the_ground_again():
    """Its own failsafe landed it meanwhile: with the maneuver kept (``fly``) the flight starts
    over from the ground, as ever; taken over to land, nothing is left to fly and it ends."""
    for airborne, then in (("fly", Phase.PREFLIGHT), ("land", Phase.DISARMED)):
        veh = _airborne(4.0)
        sup = make_supervisor(FakePlan(), airborne=airborne)

        def disarm_at_2_5s(v, msgs, sup=sup):
            if v.t_ms == 2500 and sup.phase == Phase.TAKEOVER:
                v.armed, v.x[2], v.heartbeat_due = False, 0.0, True
            return msgs
        events, _, _ = run(sup, veh, 3.0, on_step=disarm_at_2_5s)
        assert _phases(events)[:2] == [Phase.TAKEOVER, then], (airborne, _phases(events))


def test_the_cli_offers_what_the_supervisor_takes():
    import argparse

    from mavreg.cli.common import add_airborne_argument
    from mavreg.daemon.flight.phases import AIRBORNE_CHOICES, SupervisorParams
    p = argparse.ArgumentParser()
    add_airborne_argument(p)
    assert tuple(next(a for a in p._actions if a.dest == "airborne").choices) == AIRBORNE_CHOICES
    import pytest
    with pytest.raises(ValueError, match="airborne"):
        SupervisorParams(airborne="hover")
