"""The daemon behind a faulty link, sans-I/O: duplicated and reordered samples are never used
as newer state, and a telemetry outage mid-maneuver is not flown through blindly (the fault
line of mavreg.tools.faultlink between the supervisor and the harness vehicle)."""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.vehicle.messages import PX4_MAIN_AUTO, PX4_MAIN_OFFBOARD, PX4_SUB_LOITER
from mavreg.daemon.flight.state import StateAssembler
from mavreg.daemon.flight.supervisor import Phase
from mavreg.tools.faultlink import FaultLine, FaultParams
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, wire

N = 3000


def _bundle(t_ms: int) -> list:
    return [wire(mavlink2.MAVLink_attitude_quaternion_message(t_ms, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
            wire(mavlink2.MAVLink_local_position_ned_message(t_ms, 0.001 * t_ms, 0.0, -2.0, 1.0, 0.0, 0.0))]


def _feed(params: FaultParams) -> tuple[StateAssembler, list, FaultLine]:
    """N state bundles (2 ms apart, one datagram each) through ``params``; the samples made."""
    asm, line, used = StateAssembler(), FaultLine(params), []
    for k in range(N + 50):
        if k < N:
            line.push(k * 0.002, _bundle(2 * k))
        for item in line.pop_due(k * 0.002):
            for m in item:
                s = asm.add(m)
                if s is not None:
                    used.append(s.time_boot_ms)
    return asm, used, line


def test_duplicates_are_dropped_and_counted():
    asm, used, line = _feed(FaultParams(duplicate=0.2, seed=1))
    assert line.counters.duplicated > 400
    assert used == [2 * k for k in range(N)]                  # every sample once, in order
    assert asm.counters.late == 2 * line.counters.duplicated  # both parts of each copy


def test_overtaken_samples_are_dropped_and_counted():
    asm, used, line = _feed(FaultParams(reorder=0.1, reorder_s=0.01, seed=2))
    assert line.counters.reordered > 200
    assert used == sorted(used) and len(set(used)) == len(used)
    assert len(used) == N - line.counters.reordered            # an overtaken sample is never used
    assert asm.counters.late == 2 * line.counters.reordered


def test_mixed_faults_never_go_back_in_time():
    asm, used, line = _feed(FaultParams(loss=0.1, duplicate=0.1, reorder=0.1, jitter_s=0.005, seed=3))
    assert all(b > a for a, b in zip(used, used[1:]))
    assert asm.counters.late > 0


class FailsafeVehicle(SimVehicle):
    """The harness vehicle with an offboard-loss failsafe (firmware_sim's, 0.25 s): it leaves
    OFFBOARD for a hold and says so in a HEARTBEAT at once (lost, in an outage)."""

    def __init__(self, **kw):
        super().__init__(**kw)
        self.failsafe_ms = None

    def physics(self):
        if (self.armed and self.main == PX4_MAIN_OFFBOARD and self.last_target_ms is not None
                and self.t_ms - self.last_target_ms > 250):
            self.main, self.sub = PX4_MAIN_AUTO, PX4_SUB_LOITER
            self.heartbeat_due = True
            self.failsafe_ms = self.t_ms
        super().physics()


def _outage_flight(lockstep: bool, lockstep_clock: bool, outage_s: float = 0.5):
    """Fly FakePlan; 1 m into the maneuver both directions go dark for ``outage_s``.

    ``lockstep_clock``: the injected clock passes 0.1 ms per message handled (a lockstep
    world: the daemon's clock runs only while it works, the vehicle's ahead of it when
    there is nothing to answer); else it is the vehicle's time (real time)."""
    veh = FailsafeVehicle(rate_hz=250)
    sup = make_supervisor(FakePlan(length_m=3.0), lockstep=lockstep, gap_fill=False)
    clear = FaultParams()
    up, down = FaultLine(clear, "up"), FaultLine(clear, "down")
    outage_at, now, events, answered = None, 0.0, [], []
    for _ in range(int(25.0 * 250)):
        t = veh.t_ms / 1000.0
        if outage_at is None and sup.phase == Phase.MANEUVER and sup.ctx.s_m > 1.0:
            outage_at = t
            p = FaultParams(outages=((t, outage_s),))
            up, down = FaultLine(p, "up"), FaultLine(p, "down")
        due = veh.t_ms % 1000 == 0 or veh.heartbeat_due
        veh.heartbeat_due = False
        down.push(t, ([veh.heartbeat()] if due else []) + veh.outbox + veh.telemetry())
        veh.outbox = []
        for item in down.pop_due(t):
            for m in item:
                now = now + 1e-4 if lockstep_clock else t
                out = sup.handle(m, now)
                events += out.events
                for o in out.messages:
                    if o.get_type() == "SET_ACTUATOR_CONTROL_TARGET":
                        answered.append((t, sup.phase))
                    up.push(t, o)
        for o in up.pop_due(t):
            veh.receive(wire(o, 1, 191))
        events += sup.tick(now if lockstep_clock else t).events
        veh.physics()
        if sup.finished:
            break
    return sup, veh, outage_at, events, answered


def test_outage_mid_maneuver_triggers_the_failsafe_and_is_not_flown_through():
    sup, veh, t0, events, answered = _outage_flight(lockstep=True, lockstep_clock=True)
    assert veh.failsafe_ms is not None and t0 < veh.failsafe_ms / 1000 < t0 + 0.5   # the vehicle's failsafe
    after = [phase for t, phase in answered if t >= t0 + 0.5]
    assert Phase.MANEUVER not in after                          # the maneuver is not resumed
    assert sup.failure is not None and sup.failure.bound == "telemetry_gap"
    kinds = [e.kind for e in events]
    assert "recover" in kinds and "hand_over" in kinds          # reported: the gap, then the failsafe
    hand = next(e for e in events if e.kind == "hand_over")
    assert "left OFFBOARD" in hand.detail and sup.phase == Phase.ABORTED


def test_negative_control_without_lockstep_judgement_the_maneuver_resumes_blindly():
    """The same flight with the gap judged on both clocks (as before): the lockstep world's
    clock barely passes during the outage, so the maneuver went on after it."""
    sup, veh, t0, events, answered = _outage_flight(lockstep=False, lockstep_clock=True, outage_s=0.6)
    assert veh.failsafe_ms is not None
    assert Phase.MANEUVER in [phase for t, phase in answered if t >= t0 + 0.6]
    assert "recover" not in [e.kind for e in events]

