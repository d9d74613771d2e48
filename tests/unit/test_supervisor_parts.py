"""The supervisor's parts: every phase has its handler, the table is what flies, one airborne
set (the signal handler's too), and the violation and outcome records."""
from __future__ import annotations

import math

import pytest

from mavreg.daemon.jobs.app import Daemon, DaemonConfig
from mavreg.daemon.flight.gate import GateVerdict
from mavreg.daemon.flight.handlers import HANDLERS
from mavreg.daemon.flight.hover_phases import Hold
from mavreg.daemon.flight.phases import AIRBORNE, PHASE_CODES, Phase, SupervisorParams
from mavreg.daemon.flight.records import BoundViolation, Outcome
from tests.helpers.supervisor_harness import CONTROLLER, VEHICLE, FakePlan, FakeRegulator, SimVehicle, make_supervisor, run


def test_every_phase_has_one_handler_of_its_kind_and_keeps_its_log_code():
    assert set(HANDLERS) == set(Phase)
    for phase, cls in HANDLERS.items():
        kind = "control" if phase in AIRBORNE else "on_sample"
        assert callable(getattr(cls, kind, None)), (phase, cls)
    # old control logs decode with the same codes (new phases go at the end)
    assert [p.value for p in sorted(PHASE_CODES, key=PHASE_CODES.get)] == [
        "preflight", "takeoff", "hold", "run_in", "maneuver", "land", "disarmed", "aborted", "recover", "terminate",
        "takeover"]
    assert f"[{Phase.RUN_IN}]" == "[run_in]" and Phase.HOLD == "hold"


def test_the_table_is_what_flies():
    """A hold handler swapped in the supervisor's table is the one that answers the hold."""
    calls = []

    class CountingHold(Hold):
        def control(self, sample, x, out):
            calls.append(sample.time_s)
            return super().control(sample, x, out)

    sup = make_supervisor(FakePlan())
    sup.handlers[Phase.HOLD] = CountingHold(sup.flight, sup.safety)
    events, _, _ = run(sup, SimVehicle(), 60.0)
    holds = [e.time_s for e in events if e.kind == "phase" and e.phase == Phase.HOLD]
    assert sup.succeeded and len(holds) == 2
    assert calls and min(calls) >= holds[0]                  # only in the hold, every sample of it


def _daemon_in(phase_reached, flights: int | None = 1) -> tuple:
    cfg = DaemonConfig("udpout:127.0.0.1:1", CONTROLLER, None, None, SupervisorParams(), flights=flights)
    lines = []
    d = Daemon(cfg, VEHICLE, FakeRegulator, log=lines.append)
    sup = d.supervisor
    sup.offer_plan(FakePlan(), 0.0)
    veh = SimVehicle()
    for _ in range(600):
        run(sup, veh, 0.1)
        if phase_reached(sup):
            return d, veh, lines
    raise AssertionError(f"never reached: {sup.phase}")


def test_a_signal_while_landing_lets_the_landing_finish():
    """Ctrl-C in the landing (an airborne phase): the daemon keeps flying it down (it used to
    stop the stream at once, leaving the vehicle to its failsafe mid-descent); a second
    signal still stops at once."""
    d, veh, lines = _daemon_in(lambda s: s.phase == Phase.LAND and -s.last_sample.x[2] > 0.5)
    d.request_stop()
    assert not d._stop.is_set() and "landing at the next safe point" in lines[-1]
    run(d.supervisor, veh, 30.0)
    assert d.supervisor.phase == Phase.DISARMED and not veh.armed and abs(veh.x[2]) < 1e-9
    d.request_stop()
    assert d._stop.is_set()


@pytest.mark.parametrize("signalled", [True, False])
def test_serve_signalled_in_the_air_lands_then_stops(signalled):
    """``serve`` (flight after flight) signalled in the air lands, then stops; it used to begin
    the next flight and wait there for an upload until it was killed. Without the signal (the
    negative control) the landing's end begins the next flight."""
    d, veh, lines = _daemon_in(lambda s: s.phase == Phase.HOLD and s.ctx.maneuvers_done, flights=None)
    if signalled:
        d.request_stop()
    else:
        d._emit(d.supervisor.request_land(0.0))
    run(d.supervisor, veh, 30.0)
    assert d.supervisor.phase == Phase.DISARMED and not veh.armed
    d._close_flight()
    assert d._stop.is_set() == signalled and d.flight_number == (1 if signalled else 2)
    assert ("the daemon stops: a signal asked it to land, then stop" in lines) == signalled


def test_violation_and_outcome_read_as_one_line():
    v = BoundViolation("position_error", Phase.MANEUVER, 12.5, 3.25, 0.62, 0.5, "m", "distance from the path")
    assert v.describe() == ("position_error in maneuver at s=3.25 m, t=12.500 s: 0.62 m (limit 0.5 m); "
                            "distance from the path")
    o = Outcome.of(v, "recovery, then landing")
    assert o.line() == v.describe() + "; action: recovery, then landing"
    assert o.as_dict()["bound"] == "position_error" and "impact" not in o.as_dict()
    # a gate's failing verdict placed in the flight; unknown time and amount are left out
    g = GateVerdict(False, "gate_autopilot", detail="HEARTBEAT of an autopilot not spoken to").at(Phase.PREFLIGHT,
                                                                                                 math.nan)
    assert g.describe() == "gate_autopilot in preflight; HEARTBEAT of an autopilot not spoken to"
    assert not g.impact and math.isnan(g.s_m)


def undeclared_parts(cls, sup) -> list[str]:
    """The flight's parts (:class:`FlightParts`) that ``cls`` does not declare with the part's
    annotation, or that ``sup`` (an instance) does not hold as that very part."""
    import dataclasses

    from mavreg.daemon.flight.context import FlightParts
    declared = {k: v for c in reversed(cls.__mro__) for k, v in getattr(c, "__annotations__", {}).items()}
    found = []
    for f in dataclasses.fields(FlightParts):
        if declared.get(f.name) != f.type:
            found.append(f"{f.name}: not declared as {f.type}")
        elif getattr(sup, f.name, None) is not getattr(sup.parts, f.name):
            found.append(f"{f.name}: not the flight's part")
    return found


def test_the_supervisor_declares_each_of_its_parts():
    """Each part is an annotated attribute of the supervisor (editors and type checkers see
    ``sup.forecaster``), and is the flight's own part, not a copy."""
    from mavreg.daemon.flight.supervisor import Supervisor
    sup = make_supervisor(FakePlan())
    assert Supervisor.__annotations__["parts"] == "FlightParts"
    assert undeclared_parts(Supervisor, sup) == []


def test_the_parts_check_sees_a_part_undeclared_or_not_the_flights():
    from mavreg.daemon.flight.supervisor import Supervisor

    class Partial:
        __annotations__ = {k: v for k, v in Supervisor.__annotations__.items() if k != "gate"}
    sup = make_supervisor(FakePlan())
    assert undeclared_parts(Partial, sup) == ["gate: not declared as HealthGate"]
    sup.monitor = object()
    assert undeclared_parts(Supervisor, sup) == ["monitor: not the flight's part"]
