"""The two clocks: real time (wall clock) and lockstep.

Real time
    A control period every ``1/rate_hz`` wall seconds: the telemetry of t_k goes out at
    the period's start, incoming messages are handled as they arrive, and at the period's
    end the physics steps to t_{k+1} with the latest actuator target held over it. A
    target sent in answer to the telemetry (within the period) thus acts over the whole
    period, as in lockstep; one that misses the period acts a period later. Overruns
    (more than 0.1 s behind) are counted and the schedule is reset.

Lockstep
    Nothing advances until a valid MAVLink message has been heard (time frozen at 0), nor
    after a reboot until a peer is heard again (its down time itself runs as fast as it can).
    Then, period k: the downlink releases what is due at t_k (in the ideal world: the
    HEARTBEAT when due and the telemetry of t_k). If that includes n >= 1 *complete*
    state bundles (ATTITUDE_QUATERNION and LOCAL_POSITION_NED of one time, neither
    lost), datagrams are received one at a time until n valid
    offboard targets (SET_ACTUATOR_CONTROL_TARGET or SET_ATTITUDE_TARGET) have been
    *received* (counted on arrival, before the
    uplink's delay and loss, so a lost or late command does not stall the loop;
    COMMAND_LONG etc. received meanwhile enter the uplink at t_k). If n == 0 (nothing
    released yet, or a sample lost on the way) nothing is read: the peer has no sample
    to answer. Then the physics steps to t_{k+1}, handling commands as they fall due.
    Datagrams after the n-th target wait for period k+1, so a peer that answers every
    complete sample with one target gets a deterministic run.

    If a target does not arrive within ``lockstep_timeout_s`` (wall), the period counts
    as a lockstep timeout, the last command is held and the loop is *stalled*: it stops
    waiting per period and runs at ``stall_speed`` times real time (0: as fast as it
    can) until a target arrives again, which resumes waiting at once. Timeouts of the
    autopilot (failsafe, OFFBOARD precondition, heartbeat) count in simulation time.
"""
from __future__ import annotations

import time

from .engine import Engine

__all__ = ["run_realtime", "run_lockstep", "StopRun"]


class StopRun(BaseException):
    """Raised by a signal handler to end the loop cleanly."""


class _Status:
    def __init__(self, engine: Engine, quiet: bool):
        self.engine = engine
        self.quiet = quiet
        self.next_wall = time.monotonic() + 1.0

    def tick(self, now: float) -> None:
        if now >= self.next_wall:
            self.next_wall = now + 1.0
            if not self.quiet:
                print(self.engine.status_line(), flush=True)


def _done(engine: Engine, duration_s: float | None) -> bool:
    return duration_s is not None and engine.sim.t_s >= duration_s - 1e-9


def run_realtime(engine: Engine, rate_hz: int, duration_s: float | None = None,
                 quiet: bool = False) -> None:
    """Run against the wall clock until ``duration_s`` of sim time (or forever)."""
    period = 1.0 / rate_hz
    status = _Status(engine, quiet)
    start = time.monotonic()
    k0 = 0
    k = 0
    while not _done(engine, duration_s):
        engine.poll()
        engine.begin_period()
        k += 1
        deadline = start + (k - k0) * period
        now = time.monotonic()
        if now > deadline + 0.1:
            engine.counters["overruns"] += 1
            start, k0 = now, k
            deadline = now
        while now < deadline:
            if engine.link.wait_readable(deadline - now):
                engine.poll()
            now = time.monotonic()
        engine.step()
        status.tick(now)


def run_lockstep(engine: Engine, timeout_s: float = 0.1, duration_s: float | None = None,
                 quiet: bool = False, stall_speed: float = 1.0) -> None:
    """Run in lockstep (see the module docstring) until ``duration_s`` of sim time."""
    link = engine.link
    status = _Status(engine, quiet)
    period = 1.0 / engine.sim.params.rate_hz
    stalled = False
    stall_wall0 = stall_t0 = 0.0
    while not _done(engine, duration_s):
        while not link.peers and not engine.reboots.down:   # frozen until someone talks (at the
            if link.wait_readable(1.0):                     # start, and after a reboot)
                engine.poll()
            status.tick(time.monotonic())
        engine.begin_period()
        count0 = engine.targets_received
        if stalled:
            engine.poll()
            if engine.targets_received != count0:
                stalled = False
            elif stall_speed > 0:
                deadline = stall_wall0 + (engine.sim.t_s + period - stall_t0) / stall_speed
                now = time.monotonic()
                while now < deadline and engine.targets_received == count0:
                    if link.wait_readable(deadline - now):
                        engine.process_datagram()
                    now = time.monotonic()
                if engine.targets_received != count0:
                    stalled = False
        elif engine.complete_released:
            wanted = count0 + engine.complete_released
            deadline = None
            while engine.targets_received < wanted:
                if engine.process_datagram():
                    continue
                now = time.monotonic()
                if deadline is None:
                    deadline = now + timeout_s
                if now >= deadline or not link.wait_readable(deadline - now):
                    if engine.targets_received < wanted and time.monotonic() >= deadline:
                        engine.counters["lockstep_timeouts"] += 1
                        stalled = True
                        stall_wall0, stall_t0 = time.monotonic(), engine.sim.t_s
                        break
        engine.step()
        status.tick(time.monotonic())
