"""A loop that fell behind its telemetry answers the newest sample of what waited, once.

Supervisor (sans-I/O, the harness's fake vehicle on an injected clock): a read holding five
complete samples, the vehicle flying on meanwhile with the last command held, is answered
with one command, for the newest sample; the four older ones are checked and counted as
superseded; handing the same messages one read each (the negative control) answers all
five, and so does a lockstep vehicle's read (it waits for each answer). A sample with no
state part after it in its read is answered before the messages that follow it. Link (a real UDP socket, no event loop): one wake-up reads every datagram waiting and
then says the read is done, once; a backlog beyond :data:`MAX_READ_DATAGRAMS` takes two.
"""
from __future__ import annotations

import socket

from mavreg.daemon.vehicle.link import MAX_READ_DATAGRAMS, FastLink
from mavreg.daemon.flight.supervisor import Phase
from tests.helpers.supervisor_harness import FakePlan, SimVehicle, make_supervisor, run

COMMAND = "SET_ACTUATOR_CONTROL_TARGET"


def _in_the_hold(**params):
    """A supervisor (``SupervisorParams(**params)``) and its vehicle, holding after the take-off."""
    sup, veh = make_supervisor(FakePlan(), **params), SimVehicle()
    for _ in range(200):
        run(sup, veh, 0.1)
        if sup.phase == Phase.HOLD:
            return sup, veh
    raise AssertionError(f"never held: {sup.phase}")


def _backlog(veh, n: int) -> list:
    """``n`` periods of the vehicle's telemetry, flown on the command it holds."""
    msgs = []
    for _ in range(n):
        msgs += veh.telemetry()
        veh.physics()
    return msgs


def test_a_read_of_five_samples_is_answered_once_for_the_newest():
    sup, veh = _in_the_hold()
    before = sup.counters.superseded
    msgs = _backlog(veh, 5)
    newest_ms = msgs[-1].time_boot_ms
    out = sup.handle_many(msgs, veh.t_ms / 1000.0)
    assert [m.get_type() for m in out.messages].count(COMMAND) == 1
    assert sup.counters.superseded - before == 4
    assert sup.last_sample.time_boot_ms == newest_ms and sup.phase == Phase.HOLD
    assert out.log is not None and abs(out.log.time_s - newest_ms / 1000.0) < 1e-9   # the newest's record


def test_the_last_sample_of_a_read_is_answered_before_the_messages_after_it():
    """A sample with no state part after it in its read is answered at once, in order: a
    HEARTBEAT after it (here: the vehicle taken out of OFFBOARD) acts after the command."""
    from mavreg.daemon.vehicle.messages import PX4_MAIN_AUTO, PX4_SUB_LOITER
    sup, veh = _in_the_hold()
    msgs = _backlog(veh, 1)
    veh.main, veh.sub = PX4_MAIN_AUTO, PX4_SUB_LOITER
    out = sup.handle_many(msgs + [veh.heartbeat()], veh.t_ms / 1000.0)
    assert [m.get_type() for m in out.messages].count(COMMAND) == 1
    assert sup.phase == Phase.ABORTED and sup.failure.bound == "vehicle_mode"


def test_the_same_messages_one_read_each_are_answered_five_times():
    sup, veh = _in_the_hold()
    before = sup.counters.superseded
    outs = [sup.handle(m, veh.t_ms / 1000.0) for m in _backlog(veh, 5)]
    assert sum([m.get_type() for m in o.messages].count(COMMAND) for o in outs) == 5
    assert sup.counters.superseded == before


def _udp_pair():
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    rx.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tx.connect(rx.getsockname())
    return rx, tx


def _waiting(rx) -> int:
    import fcntl
    import struct
    import termios
    return struct.unpack("i", fcntl.ioctl(rx.fileno(), termios.FIONREAD, b"\0\0\0\0"))[0]


def test_one_wake_up_reads_every_datagram_waiting_and_ends_the_read_once():
    rx, tx = _udp_pair()
    got, ends = [], []
    link = FastLink("udpout", tx.getsockname()[:2], 1, 1, lambda m, t: got.append(m), None, rx,
                    on_read_end=lambda: ends.append(len(got)))
    veh = SimVehicle()
    frames = []
    for _ in range(3):
        frames += [m.get_msgbuf() for m in veh.telemetry()]
        veh.physics()
    try:
        for f in frames:
            tx.send(bytes(f))
        link._readable()
        assert len(got) == 6 and ends == [6]
        link._readable()                       # nothing waiting: the read is still ended, empty
        assert ends == [6, 6]
    finally:
        link.close()
        tx.close()


def test_a_backlog_beyond_one_reads_bound_takes_two_reads():
    rx, tx = _udp_pair()
    got, ends = [], []
    link = FastLink("udpout", tx.getsockname()[:2], 1, 1, lambda m, t: got.append(m), None, rx,
                    on_read_end=lambda: ends.append(len(got)))
    frame = bytes(SimVehicle().telemetry()[0].get_msgbuf())
    try:
        for _ in range(MAX_READ_DATAGRAMS + 10):
            tx.send(frame)
        link._readable()
        assert ends == [MAX_READ_DATAGRAMS] and _waiting(rx) > 0
        link._readable()
        assert ends == [MAX_READ_DATAGRAMS, MAX_READ_DATAGRAMS + 10]
    finally:
        link.close()
        tx.close()


def test_a_lockstep_vehicle_has_every_sample_of_a_read_answered():
    """It waits for the answer to each sample it released (it is still where the oldest says)."""
    sup, veh = _in_the_hold(lockstep=True)
    before = sup.counters.superseded
    out = sup.handle_many(_backlog(veh, 5), veh.t_ms / 1000.0)
    assert [m.get_type() for m in out.messages].count(COMMAND) == 5
    assert sup.counters.superseded == before


def test_a_read_that_ends_the_flight_leaves_the_rest_to_the_next():
    """The message that ends the flight is the last this flight takes (``Output.taken``): the
    samples after it in the read are the next flight's to answer."""
    from mavreg.daemon.vehicle.messages import PX4_MAIN_AUTO, PX4_SUB_LOITER
    sup, veh = _in_the_hold()
    veh.main, veh.sub = PX4_MAIN_AUTO, PX4_SUB_LOITER
    read = [veh.heartbeat()] + _backlog(veh, 2)
    out = sup.handle_many(read, veh.t_ms / 1000.0)
    assert sup.finished and out.taken == 1
    assert sup.handle_many(read[1:], veh.t_ms / 1000.0).taken is None      # an ended flight takes all
