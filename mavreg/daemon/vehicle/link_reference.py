"""The reference UDP link: an :class:`asyncio.DatagramProtocol` with pymavlink's generated
codec, one datagram per message (``MAVREG_IO=reference``). The daemon flies
:class:`mavreg.daemon.vehicle.link.FastLink`; this one is kept for the benchmarks' baseline and for the
agreement tests, with the same interface and the same peer rules (:mod:`mavreg.daemon.vehicle.link`).
"""
from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass, field
from typing import Callable

from pymavlink.dialects.v20 import common as mavlink2

from .link import OWN_COMPONENT_ID, LinkCounters
from .peers import PeerFilter
from ..logs.tlog import TlogWriter

__all__ = ["MavlinkLink"]


class _Writer:
    """File-like sink that pymavlink's ``MAVLink.send`` writes packed frames to."""

    def __init__(self, link: "MavlinkLink"):
        self.link = link

    def write(self, buf: bytes) -> None:
        self.link._write(buf)


@dataclass
class MavlinkLink(asyncio.DatagramProtocol):
    """MAVLink 2 over one UDP socket, to one vehicle.

    Parameters
    ----------
    kind : {"udpin", "udpout"}
    vehicle_addr : (host, port) or None
        Known for udpout; learned from the vehicle's heartbeat for udpin.
    system_id : int or None
        The vehicle's system id (the daemon uses the same, with component 191); None (``udpin``
        only): taken from the vehicle's first autopilot HEARTBEAT (:mod:`.peers`).
    vehicle_component_id : int
    on_message : callable(msg, t_recv_ns)
        Receives each decoded message from the vehicle's address.
    on_read_end : callable() or None
        Called after each datagram's messages were handed on.
    tlog : TlogWriter or None
    signing : Signing or None
        Sign what is sent, take only validly signed frames (:mod:`.signing`).
    """

    kind: str
    vehicle_addr: tuple[str, int] | None
    system_id: int | None
    vehicle_component_id: int
    on_message: Callable
    tlog: TlogWriter | None = None
    counters: LinkCounters = field(default_factory=LinkCounters)
    signing: object = None
    on_read_end: Callable | None = None

    def __post_init__(self):
        self.peer = PeerFilter(self.system_id, self.vehicle_component_id, self.vehicle_addr, self.signing)
        self.transport: asyncio.DatagramTransport | None = None
        self.last_send_ns = 0
        """``time.perf_counter_ns`` when the last rotor command was handed to ``sendto``."""
        self._stamp = False
        self.mav = mavlink2.MAVLink(_Writer(self), srcSystem=self.system_id or 0, srcComponent=OWN_COMPONENT_ID)
        self.mav.robust_parsing = True
        self.connected = asyncio.Event()
        if self.vehicle_addr is not None:
            self.connected.set()

    # -- asyncio.DatagramProtocol
    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        t_ns = time.perf_counter_ns()
        self.counters.datagrams_in += 1
        if self.vehicle_addr is not None and addr[:2] != self.vehicle_addr and not self.peer.may_move(t_ns * 1e-9):
            self.counters.foreign_address += 1
            return
        try:
            msgs = self.mav.parse_buffer(data) or []
        except mavlink2.MAVError:
            self.counters.bad_data += 1
            return
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                self.counters.bad_data += 1
                continue
            reason = self.peer.admit(msg.get_msgbuf(), addr, t_ns * 1e-9)
            if reason is not None:
                self.counters.__dict__[reason] += 1
                continue
            self.counters.messages_in += 1
            if self.tlog is not None:
                self.tlog.write(msg.get_msgbuf())
            if self.vehicle_addr is None:
                self.vehicle_addr = self.peer.addr
                self.system_id = self.peer.vehicle.system_id
                self.mav.srcSystem = self.system_id
                self.connected.set()
            elif self.peer.moves != self.counters.vehicle_moved:     # the vehicle's address moved
                self.vehicle_addr, self.counters.vehicle_moved = self.peer.addr, self.peer.moves
            self.on_message(msg, t_ns)
        if self.on_read_end is not None:
            self.on_read_end()

    def error_received(self, exc) -> None:
        self.counters.send_errors += 1

    # -- sending
    def send(self, msg) -> bool:
        """Pack and send one message to the vehicle; False while its address is unknown."""
        if self.transport is None or self.vehicle_addr is None or self.transport.is_closing():
            return False
        self._stamp = msg.get_type() == "SET_ACTUATOR_CONTROL_TARGET"
        self.mav.send(msg)
        return True

    def send_many(self, msgs) -> bool:
        """Send each message in a datagram of its own; False while the vehicle's address is unknown."""
        sent = False
        for m in msgs:
            sent = self.send(m) or sent
        return sent

    def _write(self, buf: bytes) -> None:
        if self.signing is not None:
            buf = self.signing.sign(buf)
        if self._stamp:
            self.last_send_ns = time.perf_counter_ns()
        self.transport.sendto(buf, self.vehicle_addr)
        self.counters.messages_out += 1
        if self.tlog is not None:
            self.tlog.write(buf)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()
        if self.signing is not None:
            self.signing.save()
