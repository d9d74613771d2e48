"""Flying through telemetry gaps on the prediction (real time), on the harness vehicle."""
from __future__ import annotations


from mavreg.control.estimation.forecast import Forecaster
from mavreg.daemon.flight.supervisor import Phase, Supervisor, SupervisorParams
from tests.helpers.supervisor_harness import VEHICLE, FakePlan, FakeRegulator, SimVehicle, wire

RATE = 250


def _fly(gap_s: float, fill: bool):
    """A flight whose telemetry stops for ``gap_s`` in the middle of the maneuver (the vehicle
    keeps flying); the I/O layer's timer calls ``fill_gap`` every period of the gap."""
    veh = SimVehicle(rate_hz=RATE)
    fc = Forecaster(VEHICLE, 1.0 / RATE, predict=True)
    sup = Supervisor(VEHICLE, SupervisorParams(gap_fill=fill), FakeRegulator, forecaster=fc)
    plan = FakePlan(length_m=3.0)
    sup.offer_plan(plan, 0.0)
    gap_at, sent_in_gap, events = None, 0, []
    for _ in range(int(30.0 * RATE)):
        now = veh.t_ms / 1000.0
        in_gap = gap_at is not None and now < gap_at + gap_s
        if gap_at is None and sup.phase == Phase.MANEUVER and sup.ctx.s_m > 1.0:
            gap_at, in_gap = now, True
        msgs = [veh.heartbeat()] if (veh.t_ms % 1000 == 0 or veh.heartbeat_due) else []
        veh.heartbeat_due = False
        if not in_gap:
            msgs += veh.outbox + veh.telemetry()
            veh.outbox = []
        outs = [sup.handle(m, now) for m in msgs]
        if in_gap:
            outs.append(sup.fill_gap(now + 0.5 / RATE))
        outs.append(sup.tick(now))
        for out in outs:
            events += out.events
            for o in out.messages:
                if in_gap and o.get_type() == "SET_ACTUATOR_CONTROL_TARGET":
                    sent_in_gap += 1
                veh.receive(wire(o, 1, 191))
        veh.physics()
        if sup.finished:
            break
    return sup, sent_in_gap, events


def test_a_short_gap_is_flown_on_the_prediction():
    sup, sent, _ = _fly(0.06, fill=True)
    assert sup.succeeded, sup.failure
    assert sent >= 0.06 * RATE - 2                   # a command every period of the gap
    assert sup.counters.gap_commands == sent


def test_without_filling_the_same_gap_flies_blind():
    sup, sent, _ = _fly(0.06, fill=False)
    assert sent == 0
    assert sup.counters.gap_commands == 0


def test_a_gap_past_the_horizon_stops_the_prediction_and_is_judged():
    """0.2 s: the prediction stops at its 0.1 s horizon; when samples resume the gap policy
    sees the vehicle flew blind longer than the maneuver tolerates and leaves the maneuver."""
    sup, sent, events = _fly(0.2, fill=True)
    assert 0 < sent <= 0.1 * RATE + 1
    kinds = [e.kind for e in events]
    assert "recover" in kinds or (sup.failure is not None and sup.failure.bound == "telemetry_gap")
