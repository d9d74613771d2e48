"""A vehicle that reboots (mavreg/daemon/flight/reboot.py), on the fake vehicle of
tests/helpers/supervisor_harness.py with an injected wall clock of its own: seen by its
``time_boot_ms`` going back (and the heartbeat gap named), rebuilt on the ground so that the
queued maneuver flies, a loss in the air (the stream stops; no motor stop from the daemon)."""
from __future__ import annotations

from pymavlink.dialects.v20 import common as M

from mavreg.daemon.flight.phases import Phase
from mavreg.daemon.flight.reboot import RebootDetector
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run

SET_INTERVAL = M.MAV_CMD_SET_MESSAGE_INTERVAL


class RebootingVehicle(SimVehicle):
    """The fake vehicle, which reboots at ``reboot_at_wall_s`` (its wall clock, ms) for
    ``down_s``: silent, then disarmed, in its hold mode, its clock from 0. ``needs_request``:
    after the reboot it sends no state until asked with SET_MESSAGE_INTERVAL (ArduCopter)."""

    def __init__(self, reboot_at_s: float, down_s: float = 1.5, needs_request: bool = False,
                 heartbeat_first: bool = True, **kw):
        super().__init__(**kw)
        self.wall_ms = 0
        self.reboot_at_ms = int(round(1000 * reboot_at_s))
        self.down_ms = int(round(1000 * down_s))
        self.needs_request = needs_request
        self.heartbeat_first = heartbeat_first
        self.requested = True
        self.booted_at_ms = None

    @property
    def down(self) -> bool:
        return self.reboot_at_ms <= self.wall_ms < self.reboot_at_ms + self.down_ms

    def physics(self):
        super().physics()
        self.wall_ms += int(round(self.dt * 1000))
        if self.wall_ms == self.reboot_at_ms + self.down_ms:          # up again: a new autopilot
            fresh = SimVehicle(rate_hz=int(round(1 / self.dt)))
            # the first HEARTBEAT at its clock's 0, or (not heartbeat_first) a second later
            self.t_ms = 0 if self.heartbeat_first else 20
            self.armed, self.main, self.sub = False, fresh.main, fresh.sub
            self.stream_since = self.last_target_ms = None
            self.controls = fresh.controls
            self.heartbeat_due = self.heartbeat_first
            self.requested = not self.needs_request
            self.booted_at_ms = self.wall_ms

    def receive(self, msg):
        if self.down:
            return
        if msg.get_type() == "COMMAND_LONG" and msg.command == SET_INTERVAL:
            self.requested = True
        super().receive(msg)

    def telemetry(self):
        return super().telemetry() if self.requested else []


def _silent_while_down(veh, msgs):
    return [] if veh.down else msgs


def _wall(veh):
    return veh.wall_ms / 1000.0


def _fly(veh, seconds=60.0, plan_at_s=None):
    sup = make_supervisor(None if plan_at_s is not None else FakePlan())
    events, _, sent = [], [], []

    def step(v, msgs):
        if plan_at_s is not None and v.wall_ms == int(round(1000 * plan_at_s)):
            sup.offer_plan(FakePlan(), _wall(v))
        return _silent_while_down(v, msgs)
    end_ms = veh.wall_ms + int(round(1000 * seconds))
    while veh.wall_ms < end_ms:          # on after the flight is over: the vehicle comes back
        ev, _, st = run(sup, veh, seconds if not sup.finished else veh.dt, on_step=step, clock=_wall)
        events += ev
        sent += st
    return sup, events, sent


def _motor_stops(sent) -> list:
    return [m for _, m in sent if m.get_type() == "COMMAND_LONG" and m.command == 400 and m.param2 == 21196]


def test_the_detector_takes_a_late_part_for_late_and_a_clock_one_second_back_for_a_reboot():
    d = RebootDetector(back_s=1.0)
    for t_wall, t_ms in ((0.0, 5000), (1.0, 6000)):
        d.heartbeat(t_wall)
        assert d.part(M.MAVLink_local_position_ned_message(t_ms, 0, 0, 0, 0, 0, 0), t_wall) is None
    assert d.part(M.MAVLink_attitude_message(5200, 0, 0, 0, 0, 0, 0), 1.1) is None     # 0.8 s late
    d.heartbeat(3.5)                                                                  # 2.5 s gap
    seen = d.part(M.MAVLink_attitude_message(40, 0, 0, 0, 0, 0, 0), 3.6)
    assert (seen.from_s, seen.to_s, seen.heartbeat_gap_s) == (6.0, 0.04, 2.5)
    assert seen.describe() == "time_boot_ms went back from 6.000 to 0.040 s after a 2.5 s heartbeat gap"
    assert d.part(M.MAVLink_attitude_message(60, 0, 0, 0, 0, 0, 0), 3.7) is None      # the new clock goes on


def test_a_reboot_on_the_ground_is_rebuilt_and_the_next_upload_flies():
    veh = RebootingVehicle(reboot_at_s=3.0, down_s=1.5)
    sup, events, sent = _fly(veh, 60.0, plan_at_s=6.0)
    seen = [e for e in events if e.kind == "vehicle_rebooted"]
    assert len(seen) == 1 and sup.counters.reboots == 1
    assert "went back from 2.996 to 0.000 s after a 2.5 s heartbeat gap" in seen[0].detail, seen[0].detail
    assert "on the ground" in seen[0].detail
    assert sup.succeeded and not veh.armed, sup.failure
    arms = [t for t, m in sent if m.get_type() == "COMMAND_LONG" and m.command == 400 and m.param1 == 1.0]
    assert arms and all(t < 20_000 for t in arms)       # armed after the reboot, on the new clock
    assert sup.timesync.estimate() is not None and not _motor_stops(sent)


def test_an_ardupilot_that_sends_nothing_after_its_reboot_is_asked_for_its_telemetry_again():
    veh = RebootingVehicle(reboot_at_s=3.0, down_s=2.0, needs_request=True)
    sup, events, sent = _fly(veh, 60.0, plan_at_s=8.0)
    boot = veh.booted_at_ms
    asked = [t for t, m in sent if m.get_type() == "COMMAND_LONG" and m.command == SET_INTERVAL and t < 5000]
    assert asked, "no SET_MESSAGE_INTERVAL after the reboot"
    assert sup.counters.reboots == 1 and sup.succeeded, sup.failure
    assert boot == 5000


def test_a_reboot_in_the_air_longer_than_the_stale_timeout_is_a_lost_link_then_named():
    veh = RebootingVehicle(reboot_at_s=8.0, down_s=1.5)
    sup, events, sent = _fly(veh, 20.0)
    f = sup.failure
    assert sup.phase == Phase.ABORTED and f.bound == "link_lost", f
    assert sup.counters.reboots == 1 and "the vehicle rebooted (time_boot_ms went back" in f.action, f.action
    assert not _motor_stops(sent)
    after = [t for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and t >= 8000]
    assert not after                                    # the stream stopped for good


def test_a_quick_reboot_in_the_air_that_says_disarmed_first_is_a_loss_named_a_reboot():
    veh = RebootingVehicle(reboot_at_s=8.0, down_s=0.3)   # back before the stale timeout (lockstep)
    sup, events, sent = _fly(veh, 20.0)
    f = sup.failure
    assert sup.phase == Phase.ABORTED and f.bound == "vehicle_mode" and "armed=False" in f.detail, f
    assert f.action.endswith("then the vehicle rebooted (time_boot_ms went back from 7.996 to 0.000 s after "
                             "a 1.3 s heartbeat gap)"), f.action
    assert not _motor_stops(sent)
    assert not [t for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and t >= 8000]


def test_a_quick_reboot_in_the_air_seen_by_its_clock_first_is_a_loss():
    veh = RebootingVehicle(reboot_at_s=8.0, down_s=0.3, heartbeat_first=False)
    sup, events, sent = _fly(veh, 20.0)
    f = sup.failure
    assert sup.phase == Phase.ABORTED and f.bound == "vehicle_rebooted", f
    assert "in the air" in f.detail and "went back from" in f.detail
    assert f.action == "command stream stopped (vehicle failsafe)"
    assert not _motor_stops(sent)
    assert not [t for t, m in sent if m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and t >= 8000]


def _leaves(obj, prefix: str = "") -> dict:
    """Every field of a context, nested groups opened: dotted path -> value."""
    import dataclasses
    found = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            found.update(_leaves(v, f"{prefix}{f.name}."))
        else:
            found[prefix + f.name] = v
    return found


def _set_everywhere(obj, value_of) -> None:
    import dataclasses
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            _set_everywhere(v, value_of)
        else:
            setattr(obj, f.name, value_of(f.name))


BOOT_KEYED = {"commands.arm_requested", "commands.ground_end_wall_s"}
"""Beside what the vehicle said (``heard.*``) and every ``*_vehicle_s``: what it was asked."""


def reboot_findings(context_cls) -> list[str]:
    """The fields ``context_cls().after_reboot()`` gets wrong: one keyed to the old boot (every
    ``*_vehicle_s``, what the vehicle said, what it was asked) kept, or one of the flight's own lost."""
    import math
    fresh, ctx = _leaves(context_cls()), context_cls()
    _set_everywhere(ctx, lambda n: 12.5 if n.endswith("_s") else "set")
    after = _leaves(ctx.after_reboot())
    found = [f"{n}: missing" for n in fresh.keys() - after.keys()]
    for n, got in sorted(after.items()):
        boot = n.endswith("_vehicle_s") or n.startswith("heard.") or n in BOOT_KEYED
        want = fresh[n] if boot else (12.5 if n.endswith("_s") else "set")
        if not (got == want or (isinstance(want, float) and math.isnan(want) and math.isnan(got))):
            found.append(f"{n}: {'kept across' if boot else 'lost in'} a reboot")
    return found


def test_the_context_after_a_reboot_is_fresh_on_the_old_boot_and_keeps_the_rest():
    """Every ``*_vehicle_s`` field of the context, what the vehicle said in its last boot and what
    it was asked go back to a fresh context's values; the flight's own state (its queue, its
    outcome) stays. A field added later is fresh unless :meth:`FlightContext.after_reboot` keeps it."""
    from mavreg.daemon.flight.context import FlightContext
    names = _leaves(FlightContext()).keys()
    assert {"heard.status", "heard.last_sample", "landing.spool_down_start_vehicle_s", "pending"} <= names
    assert reboot_findings(FlightContext) == []


def test_the_reboot_check_sees_a_field_kept_on_the_old_clock_or_one_lost():
    """Negative controls: a rebuild that keeps a field of the old clock, or loses the queue, fails."""
    import dataclasses

    from mavreg.daemon.flight.context import FlightContext

    class Keeps(FlightContext):
        def after_reboot(self):
            return dataclasses.replace(super().after_reboot(), phase_start_vehicle_s=self.phase_start_vehicle_s)

    class Loses(FlightContext):
        def after_reboot(self):
            return dataclasses.replace(super().after_reboot(), pending=[])
    assert reboot_findings(Keeps) == ["phase_start_vehicle_s: kept across a reboot"]
    assert reboot_findings(Loses) == ["pending: lost in a reboot"]


def test_a_reboot_in_the_air_that_ends_the_flight_is_named_by_the_next_flight_of_the_same_daemon():
    """ArduCopter in ``serve``: the link is lost in the air (the flight ends aborted), the new
    boot's disarmed HEARTBEAT begins the next flight, and its state comes only when asked for:
    the next flight's supervisor goes on from the last one's view of the vehicle's clock."""
    veh = RebootingVehicle(reboot_at_s=8.0, down_s=2.0, needs_request=True)
    first = make_supervisor(FakePlan())
    run(first, veh, 20.0, on_step=_silent_while_down, clock=_wall)
    assert first.phase == Phase.ABORTED and first.failure.bound == "link_lost" and veh.down, first.failure
    assert first.counters.reboots == 0                  # nothing of the new boot yet
    second = make_supervisor(None)                      # serve's next flight, waiting for an upload
    second.reboots.carry_on(first.reboots)
    events, _, sent = run(second, veh, 20.0, on_step=_silent_while_down, clock=_wall)
    seen = [e for e in events if e.kind == "vehicle_rebooted"]
    assert len(seen) == 1 and second.counters.reboots == 1, [e.kind for e in events]
    assert "s (the boot the previous flight flew) to" in seen[0].detail and "on the ground" in seen[0].detail, seen[0]
    assert not _motor_stops(sent) and second.phase == Phase.PREFLIGHT


def test_a_fresh_detector_knows_no_earlier_boot():
    d, fresh = RebootDetector(), RebootDetector()
    d.part(M.MAVLink_attitude_message(90_000, 0, 0, 0, 0, 0, 0), 0.0)
    fresh.carry_on(RebootDetector())
    assert fresh.part(M.MAVLink_attitude_message(40, 0, 0, 0, 0, 0, 0), 1.0) is None
    fresh.carry_on(d)
    assert fresh.part(M.MAVLink_attitude_message(95_000, 0, 0, 0, 0, 0, 0), 2.0) is None   # the same boot goes on
