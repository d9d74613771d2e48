"""A refusal before take-off ends the flight at once, with its cause in one line, whatever the
check that refused (the fake vehicle of tests/helpers/supervisor_harness.py; the injected
clock is the vehicle's time, so "at once" is measured on it)."""
from __future__ import annotations

import math
from dataclasses import replace

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.envelope import EnvelopeParams
from mavreg.config.vehicle import with_dialect, with_output
from mavreg.daemon.flight.phases import Phase
from mavreg.daemon.flight.supervisor import Supervisor, SupervisorParams
from tests.helpers.supervisor_harness import VEHICLE, FakePlan, FakeRegulator, SimVehicle, make_supervisor, run, wire

STEP_S = SimVehicle().dt


def _rates_supervisor(dialect=None):
    vehicle = with_dialect(with_output(VEHICLE, "rates"), dialect)
    sup = Supervisor(vehicle, SupervisorParams(), FakeRegulator)
    sup.offer_plan(FakePlan(), 0.0)
    return sup


CASES = {
    # name: (supervisor, vehicle, the bound of the refusal, words of its one line)
    "autopilot": (lambda: make_supervisor(FakePlan()), lambda: SimVehicle(autopilot=mavlink2.MAV_AUTOPILOT_SLUGS),
                  "gate_autopilot", "neither PX4"),
    "generic_rates": (_rates_supervisor, lambda: SimVehicle(autopilot=mavlink2.MAV_AUTOPILOT_GENERIC),
                      "gate_autopilot", "--dialect px4|ardupilot"),
    "contradicted": (lambda: _rates_supervisor("ardupilot"), SimVehicle, "gate_autopilot", "announces PX4"),
    "parameter": (lambda: make_supervisor(FakePlan()),
                  lambda: SimVehicle(params={"COM_OF_LOSS_T": 0.5, "COM_OBL_RC_ACT": 6.0}),
                  "gate_parameter", "COM_OBL_RC_ACT is 6"),
    "geofence": (lambda: make_supervisor(FakePlan(), envelope=replace(EnvelopeParams(), geofence_ceiling_m=1.0)),
                 SimVehicle, "gate_plan_geofence", "above the geofence ceiling"),
    "no_timesync": (lambda: make_supervisor(FakePlan()), lambda: SimVehicle(answer_timesync=False),
                    "gate_no_timesync", "fixed_delay_s"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_every_refusal_on_the_ground_ends_the_flight_at_once(case):
    """Disarmed on the ground, nothing left to wait for: the refusal and the end of the flight
    come with the same message (no HEARTBEAT is waited for), the vehicle never armed."""
    make_sup, make_veh, bound, words = CASES[case]
    sup, veh = make_sup(), make_veh()
    events, _, sent = run(sup, veh, 15.0)
    refused = next(e for e in events if e.kind == "refused")
    end = next(e for e in events if e.kind == "phase" and e.phase == Phase.DISARMED)
    assert sup.finished and sup.phase == Phase.DISARMED and not sup.succeeded and not veh.armed
    assert events.index(end) == events.index(refused) + 1           # in the same output, in order
    assert end.time_s == refused.time_s or math.isnan(refused.time_s) and math.isnan(end.time_s)
    f = sup.failure
    assert f.bound == bound and f.phase == Phase.PREFLIGHT and words in f.line(), f.line()
    assert len(f.line().splitlines()) == 1 and "staying on the ground" in f.action
    assert not any(m.get_type() == "COMMAND_LONG" and m.command == 400 and m.param1 == 1.0 for _, m in sent)


def test_an_unsupported_vehicle_is_refused_at_its_first_heartbeat_without_telemetry():
    """A vehicle mavreg does not speak to need not stream a state for the refusal: its first
    HEARTBEAT ends the flight (before, the refusal waited for a state sample that such a
    vehicle is never asked for, and ``fly`` ran to its timeout)."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(autopilot=mavlink2.MAV_AUTOPILOT_SLUGS)
    out = sup.handle(veh.heartbeat(), 0.0)
    assert sup.finished and sup.failure.bound == "gate_autopilot" and sup.last_sample is None
    assert [e.kind for e in out.events] == ["refused", "phase"]
    assert not any(m.get_type() == "COMMAND_LONG" for m in out.messages)   # nothing asked of it


def test_an_armed_refusal_disarms_then_ends_and_an_unanswered_disarm_ends_within_its_bound():
    """A link too slow is refused after OFFBOARD, with the vehicle armed: the daemon disarms
    it and the flight ends on its HEARTBEAT; a vehicle that drops the disarms is left to its
    failsafe after ``ground_disarm_timeout_s`` (injected clock)."""
    sup = make_supervisor(FakePlan(), link_health=lambda: (0.2, 0.001))
    veh = SimVehicle()
    events, _, _ = run(sup, veh, 10.0)
    refused = next(e for e in events if e.kind == "refused")
    end = next(e for e in events if e.kind == "phase")
    assert refused.phase == Phase.PREFLIGHT and "disarming" in refused.detail
    assert end.phase == Phase.DISARMED and end.time_s - refused.time_s <= 2 * STEP_S and not veh.armed
    assert sup.failure.bound == "gate_link_delay"

    sup = make_supervisor(FakePlan(), link_health=lambda: (0.2, 0.001))
    veh = SimVehicle(ignore_disarm=10_000)
    events, _, _ = run(sup, veh, 10.0)
    refused = next(e for e in events if e.kind == "refused")
    end = next(e for e in events if e.kind == "phase")
    limit = SupervisorParams().ground_disarm_timeout_s
    assert end.phase == Phase.ABORTED and "did not report disarmed" in end.detail
    assert limit < end.time_s - refused.time_s <= limit + 2 * STEP_S
    assert sup.failure.bound == "gate_link_delay" and sup.failure.action.endswith("disarm not confirmed")


def test_a_land_request_before_take_off_ends_the_flight_the_same_way():
    """Before the vehicle arms: at once; armed (it arms 0.1 s after the first sample): one
    disarm at once, and the flight ends on the HEARTBEAT that reports it disarmed."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 0.02)
    out = sup.request_land(veh.t_ms / 1000)
    assert sup.phase == Phase.DISARMED and "nothing to fly" in out.events[-1].detail and not veh.armed
    sup = make_supervisor(FakePlan())
    veh = SimVehicle()
    run(sup, veh, 0.5)
    assert veh.armed
    out = sup.request_land(veh.t_ms / 1000)
    (disarm,) = [m for m in out.messages if m.get_type() == "COMMAND_LONG"]
    assert disarm.command == 400 and disarm.param1 == 0.0 and sup.phase == Phase.PREFLIGHT
    veh.receive(disarm)
    events, _, _ = run(sup, veh, 1.0)
    assert sup.phase == Phase.DISARMED and events[-1].time_s - 0.5 <= 2 * STEP_S


def test_a_land_request_before_the_first_sample_still_retries_the_disarm():
    """Armed (by someone else) on the ground, as its landed state says, and no state sample yet,
    so no vehicle time: the disarm goes out at once, and is repeated once samples come (a retry
    timer started without a vehicle time must not block them). Without the landed state the
    vehicle may be flying: it is left armed (tests/unit/test_takeover.py)."""
    sup = make_supervisor(FakePlan())
    veh = SimVehicle(ignore_disarm=10_000)
    veh.armed = True
    sup.handle(veh.heartbeat(), 0.0)
    sup.handle(wire(mavlink2.MAVLink_extended_sys_state_message(0, mavlink2.MAV_LANDED_STATE_ON_GROUND)), 0.0)
    out = sup.request_land(0.0)
    assert [m.command for m in out.messages if m.get_type() == "COMMAND_LONG"] == [400]
    _, _, sent = run(sup, veh, 0.9)
    disarms = [t for t, m in sent if m.get_type() == "COMMAND_LONG" and m.command == 400 and m.param1 == 0.0]
    assert len(disarms) == 2 and disarms[1] - disarms[0] == 500          # every command_retry_s
