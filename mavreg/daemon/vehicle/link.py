"""The UDP link to the vehicle: datagrams <-> MAVLink 2 messages.

No flight logic here. Two implementations with one interface (``send``, ``send_many``,
``counters``, ``connected``, ``close``), chosen by :func:`open_link`:

- :class:`FastLink` (default): a non-blocking socket watched with ``loop.add_reader``; each
  wake-up reads every waiting datagram (``recvfrom`` until it would block) and decodes it
  with the precompiled codec of :mod:`mavreg.transport.wire`; the messages of one output
  (a rotor command and the TIMESYNC request that travels with it) leave in **one**
  datagram, one ``sendto``. Once the vehicle has sent an ATTITUDE_QUATERNION, its
  ATTITUDE frames (which the state assembler then ignores) are logged but not decoded.
- :class:`~mavreg.daemon.vehicle.link_reference.MavlinkLink` (the reference path, ``MAVREG_IO=reference``): an
  :class:`asyncio.DatagramProtocol` with pymavlink's generated codec, one datagram per
  message. Kept for the benchmarks' baseline and for agreement tests.

Both

- parse each datagram with robust parsing (bad data counted), log every frame in and out
  to the ``.tlog``, and hand each decoded message to a callback with the time the
  datagram was read (``time.perf_counter_ns``), and once a read is done (every datagram
  that was waiting; the reference path: one datagram) tell ``on_read_end()``;
- take a frame only if :class:`mavreg.daemon.vehicle.peers.PeerFilter` does: the vehicle's
  system/component id (the system id pinned, or on ``udpin:`` taken from its first
  autopilot HEARTBEAT), from the vehicle's address (fixed for ``udpout:HOST:PORT``,
  learned from the vehicle's first HEARTBEAT for ``udpin:HOST:PORT``, moved by it after a silence),
  and, with a signing key (:mod:`mavreg.transport.signing`), validly signed and not replayed;
  everything else is dropped and counted, and neither logged nor handed on;
- sign every frame they send when signing is on;
- pack outgoing messages with the vehicle's system id and component id 191
  (MAV_COMP_ID_ONBOARD_COMPUTER); nothing is sent before the vehicle is heard on ``udpin:``,
  so a system id taken from its HEARTBEAT is the one every frame carries.
"""
from __future__ import annotations

import asyncio
import os
import socket
import time
from dataclasses import dataclass
from typing import Callable

from pymavlink.dialects.v20 import common as mavlink2

from .peers import PeerFilter
from ..logs.tlog import TlogWriter
from .url import VEHICLE_URL_FORMS, parse_url
from ...transport.wire import Wire

__all__ = ["parse_url", "VEHICLE_URL_FORMS", "LinkCounters", "FastLink", "open_link", "OWN_COMPONENT_ID",
           "IO_ENV", "io_impl", "MAX_READ_DATAGRAMS"]

IO_ENV = "MAVREG_IO"
_AFTER_QUATERNION = frozenset({mavlink2.MAVLINK_MSG_ID_ATTITUDE})
"""Not decoded once the vehicle has sent ATTITUDE_QUATERNION (the state assembler then
ignores ATTITUDE): logged to the ``.tlog`` and counted under ``not_decoded`` only."""
"""Environment variable choosing the link: ``fast`` (default) or ``reference``."""
_MAX_DATAGRAM = 65535
MAX_READ_DATAGRAMS = 512
"""Datagrams one wake-up of :class:`FastLink` reads at most (about 0.2 s of a 500 Hz vehicle's
telemetry): a backlog is read at once, and the loop still runs its timers between reads."""

OWN_COMPONENT_ID = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER


@dataclass
class LinkCounters:
    datagrams_in: int = 0
    messages_in: int = 0
    messages_out: int = 0
    bad_data: int = 0
    foreign_address: int = 0
    send_errors: int = 0
    not_decoded: int = 0
    """Frames logged but not decoded (the fast link: ATTITUDE once quaternions come)."""
    foreign_system: int = 0
    """Frames of another system/component id than the vehicle's (:mod:`.peers`)."""
    unsigned: int = 0
    bad_signature: int = 0
    replayed: int = 0
    setup_signing: int = 0
    """With signing on: frames dropped as unsigned, wrongly signed, replayed; and
    SETUP_SIGNING frames, always dropped."""
    vehicle_moved: int = 0      # udpin: times the vehicle's address moved (a restarted autopilot: .peers)
    garbage_bytes: int = 0
    """A serial or TCP link: bytes that were no part of a valid frame (:mod:`mavreg.transport.framing`;
    each broken frame also counts once under ``bad_data``)."""


def io_impl() -> str:
    """The link implementation :envvar:`MAVREG_IO` asks for (``fast`` when unset).

    Raises ValueError with a one-line reason on any other value.
    """
    impl = os.environ.get(IO_ENV, "fast")
    if impl not in ("fast", "reference"):
        raise ValueError(f"{IO_ENV}={impl!r}: expected 'fast' or 'reference'")
    return impl


class FastLink:
    """MAVLink 2 over one non-blocking UDP socket, to one vehicle (see the module docstring).

    Parameters are those of :class:`MavlinkLink`, plus the bound socket.
    """

    def __init__(self, kind: str, vehicle_addr, system_id: int | None, vehicle_component_id: int,
                 on_message: Callable, tlog: TlogWriter | None, sock: socket.socket, signing=None,
                 on_read_end: Callable | None = None):
        self.kind = kind
        self.vehicle_addr = vehicle_addr
        self.system_id = system_id
        self.vehicle_component_id = vehicle_component_id
        self.on_message = on_message
        self.on_read_end = on_read_end
        self.tlog = tlog
        self.counters = LinkCounters()
        self.sock = sock
        self.wire = Wire(system_id or 0, OWN_COMPONENT_ID)    # identified once the vehicle is heard
        self.signing = signing
        self.peer = PeerFilter(system_id, vehicle_component_id, vehicle_addr, signing)
        self.connected = asyncio.Event()
        if vehicle_addr is not None:
            self.connected.set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._closed = False
        self.last_send_ns = 0
        """``time.perf_counter_ns`` when the last datagram was handed to ``sendto``."""
        self._skip: frozenset = frozenset()

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        """Watch the socket on ``loop``."""
        self._loop = loop
        loop.add_reader(self.sock.fileno(), self._readable)

    def _readable(self) -> None:
        """Read every datagram waiting (not only one per wake-up; at most
        :data:`MAX_READ_DATAGRAMS`, the rest at the next), then tell ``on_read_end``."""
        recv = self.sock.recvfrom
        try:
            for _ in range(MAX_READ_DATAGRAMS):
                if self._closed:
                    break
                try:
                    data, addr = recv(_MAX_DATAGRAM)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:                  # e.g. an ICMP error reported for an earlier send
                    self.counters.send_errors += 1
                    break
                self.datagram_received(data, addr)
        finally:
            if self.on_read_end is not None:
                self.on_read_end()

    def datagram_received(self, data: bytes, addr) -> None:
        """One datagram, just read.

        Each message is handed on with the time it is taken up (``time.perf_counter_ns``):
        a datagram holding two state bundles (released together by a jittery link) gets the
        second one's latency counted from when the daemon turns to it, as the reference
        path, which reads one message per datagram, counts it."""
        c, now_s = self.counters, time.perf_counter_ns() * 1e-9
        c.datagrams_in += 1
        if self.vehicle_addr is not None and addr[:2] != self.vehicle_addr and not self.peer.may_move(now_s):
            c.foreign_address += 1
            return
        try:
            msgs = self.wire.parse(data, self._skip)
        except mavlink2.MAVError:
            c.bad_data += 1
            return
        tlog = self.tlog
        admit = self.peer.admit
        for msg in msgs:
            # each frame is logged just before it is handled: the command answering a sample
            # follows that sample in the .tlog (mavreg identify pairs them so)
            if type(msg) is bytes:           # a frame the daemon has no use for: logged only
                if (reason := admit(msg, addr, now_s)) is not None:
                    c.__dict__[reason] += 1
                    continue
                c.messages_in += 1
                c.not_decoded += 1
                if tlog is not None:
                    tlog.write(msg)
                continue
            if msg._type == "BAD_DATA":
                c.bad_data += 1
                continue
            if (reason := admit(msg._msgbuf, addr, now_s)) is not None:
                c.__dict__[reason] += 1
                continue
            c.messages_in += 1
            if tlog is not None:
                tlog.write(msg._msgbuf)
            if msg._type == "ATTITUDE_QUATERNION" and not self._skip:
                # the state assembler ignores ATTITUDE from now on (mavreg.daemon.flight.state)
                self._skip = _AFTER_QUATERNION
            if self.vehicle_addr is None:    # the filter took the vehicle's first HEARTBEAT
                self.vehicle_addr = self.peer.addr
                self.system_id = self.peer.vehicle.system_id
                self.wire.identify(self.system_id)
                self.connected.set()
            elif self.peer.moves != c.vehicle_moved:     # the vehicle's address moved (.peers)
                self.vehicle_addr, c.vehicle_moved = self.peer.addr, self.peer.moves
            self.on_message(msg, time.perf_counter_ns())

    def send(self, msg) -> bool:
        """Pack and send one message to the vehicle; False while its address is unknown."""
        return self.send_many((msg,))

    def send_many(self, msgs) -> bool:
        """Pack the messages into one datagram, one ``sendto``; False if nothing was sent."""
        if self._closed or self.vehicle_addr is None or not msgs:
            return False
        pack = self.wire.pack
        frames = [pack(m) for m in msgs]
        if self.signing is not None:
            sign = self.signing.sign
            frames = [sign(f) for f in frames]
        data = frames[0] if len(frames) == 1 else b"".join(frames)
        self.last_send_ns = time.perf_counter_ns()
        if not self._transmit(data):
            self.counters.send_errors += 1
            return False
        self.counters.messages_out += len(frames)
        if self.tlog is not None:
            self.tlog.write_many(frames)
        return True

    def _transmit(self, data: bytes) -> bool:
        """Hand one datagram to the socket; False if it refused it."""
        try:
            self.sock.sendto(data, self.vehicle_addr)
        except (BlockingIOError, InterruptedError, OSError):
            return False
        return True

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._loop is not None and not self._loop.is_closed():
            self._loop.remove_reader(self.sock.fileno())
        self.sock.close()
        if self.signing is not None:
            self.signing.save()


async def open_link(url: str, system_id: int | None, vehicle_component_id: int, on_message: Callable,
                    tlog: TlogWriter | None, impl: str | None = None, signing=None, on_closed=None,
                    on_read_end: Callable | None = None):
    """Create the UDP endpoint for ``url`` and return its link; or open the serial port or the
    TCP connection (:func:`mavreg.daemon.vehicle.stream_link.open_stream_link`; ``on_closed(line)`` is
    told when that stream ends, and ``impl`` does not apply).

    ``system_id``: the vehicle's; None only for ``udpin:``, ``serial:`` and ``tcp:`` (taken
    from its first autopilot HEARTBEAT; on ``udpout:`` the daemon speaks first, so it must
    know it: ValueError).

    ``impl``: ``fast`` (:class:`FastLink`) or ``reference`` (:class:`MavlinkLink`);
    default: :func:`io_impl` (the :envvar:`MAVREG_IO` environment variable).
    ``signing``: a :class:`mavreg.transport.signing.Signing`, or None (signing off).
    ``on_read_end()``: called after each read of the link has handed on its messages (the
    daemon handles a read's messages together: :meth:`mavreg.daemon.jobs.app.Daemon._on_read_end`).
    """
    kind, host, port = parse_url(url)
    if kind in ("serial", "tcp"):
        from .stream_link import open_stream_link
        return await open_stream_link(url, system_id, vehicle_component_id, on_message, tlog, signing, on_closed,
                                      on_read_end)
    if system_id is None and kind != "udpin":
        raise ValueError(f"vehicle URL {url!r}: on udpout the vehicle's system id must be given")
    impl = io_impl() if impl is None else impl
    loop = asyncio.get_running_loop()
    vehicle = (host, port) if kind == "udpout" else None
    local = (host, 0) if kind == "udpout" else (host, port)
    if impl == "reference":
        from .link_reference import MavlinkLink
        proto = MavlinkLink(kind, vehicle, system_id, vehicle_component_id, on_message, tlog,
                            signing=signing, on_read_end=on_read_end)
        await loop.create_datagram_endpoint(lambda: proto, local_addr=local)
        return proto
    info = socket.getaddrinfo(local[0], local[1], type=socket.SOCK_DGRAM)[0]
    sock = socket.socket(info[0], socket.SOCK_DGRAM)
    try:
        sock.setblocking(False)
        sock.bind(info[4])
    except OSError:
        sock.close()
        raise
    if vehicle is not None:
        vehicle = socket.getaddrinfo(host, port, family=info[0], type=socket.SOCK_DGRAM)[0][4][:2]
    link = FastLink(kind, vehicle, system_id, vehicle_component_id, on_message, tlog, sock, signing, on_read_end)
    link.start(loop)
    return link
