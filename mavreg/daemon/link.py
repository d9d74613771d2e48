"""Thin asyncio UDP adapter: datagrams <-> pymavlink's generated MAVLink 2 codec.

No flight logic here. :class:`MavlinkLink` is an :class:`asyncio.DatagramProtocol` that

- parses each datagram with ``pymavlink.dialects.v20.common.MAVLink`` (robust parsing,
  bad data counted), logs every frame in and out to the ``.tlog``, and hands each decoded
  message to a callback;
- accepts datagrams only from the vehicle's address: fixed for ``udpout:HOST:PORT``,
  learned from the first HEARTBEAT of the vehicle's system/component id for
  ``udpin:HOST:PORT``; everything else is dropped and counted;
- packs outgoing messages with the daemon's own system id and component id 191
  (MAV_COMP_ID_ONBOARD_COMPUTER).
"""
from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass, field
from typing import Callable

from pymavlink.dialects.v20 import common as mavlink2

from .tlog import TlogWriter

__all__ = ["parse_url", "LinkCounters", "MavlinkLink", "open_link", "OWN_COMPONENT_ID"]

OWN_COMPONENT_ID = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER


def parse_url(url: str) -> tuple[str, str, int]:
    """``udpin:HOST:PORT`` or ``udpout:HOST:PORT`` -> (kind, host, port).

    Raises ValueError with a one-line reason on anything else.
    """
    parts = url.split(":")
    if len(parts) != 3 or parts[0] not in ("udpin", "udpout"):
        raise ValueError(f"vehicle URL {url!r}: expected udpin:HOST:PORT or udpout:HOST:PORT")
    try:
        port = int(parts[2])
    except ValueError:
        raise ValueError(f"vehicle URL {url!r}: port {parts[2]!r} is not a number") from None
    if not 0 <= port <= 65535 or (parts[0] == "udpout" and port == 0):
        raise ValueError(f"vehicle URL {url!r}: port out of range")
    return parts[0], parts[1], port


@dataclass
class LinkCounters:
    datagrams_in: int = 0
    messages_in: int = 0
    messages_out: int = 0
    bad_data: int = 0
    foreign_address: int = 0
    send_errors: int = 0


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
    system_id, vehicle_component_id : int
        The vehicle's ids (the daemon uses the same system id and component 191).
    on_message : callable(msg, t_recv_ns)
        Receives each decoded message from the vehicle's address.
    tlog : TlogWriter or None
    """

    kind: str
    vehicle_addr: tuple[str, int] | None
    system_id: int
    vehicle_component_id: int
    on_message: Callable
    tlog: TlogWriter | None = None
    counters: LinkCounters = field(default_factory=LinkCounters)

    def __post_init__(self):
        self.transport: asyncio.DatagramTransport | None = None
        self.mav = mavlink2.MAVLink(_Writer(self), srcSystem=self.system_id, srcComponent=OWN_COMPONENT_ID)
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
        if self.vehicle_addr is not None and addr[:2] != self.vehicle_addr:
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
            self.counters.messages_in += 1
            if self.tlog is not None:
                self.tlog.write(msg.get_msgbuf())
            if (self.vehicle_addr is None and msg.get_type() == "HEARTBEAT"
                    and msg.get_srcSystem() == self.system_id
                    and msg.get_srcComponent() == self.vehicle_component_id):
                self.vehicle_addr = tuple(addr[:2])
                self.connected.set()
            self.on_message(msg, t_ns)

    def error_received(self, exc) -> None:
        self.counters.send_errors += 1

    # -- sending
    def send(self, msg) -> bool:
        """Pack and send one message to the vehicle; False while its address is unknown."""
        if self.transport is None or self.vehicle_addr is None or self.transport.is_closing():
            return False
        self.mav.send(msg)
        return True

    def _write(self, buf: bytes) -> None:
        self.transport.sendto(buf, self.vehicle_addr)
        self.counters.messages_out += 1
        if self.tlog is not None:
            self.tlog.write(buf)

    def close(self) -> None:
        if self.transport is not None:
            self.transport.close()


async def open_link(url: str, system_id: int, vehicle_component_id: int, on_message: Callable,
                    tlog: TlogWriter | None) -> MavlinkLink:
    """Create the UDP endpoint for ``url`` and return its :class:`MavlinkLink`."""
    kind, host, port = parse_url(url)
    loop = asyncio.get_running_loop()
    if kind == "udpout":
        proto = MavlinkLink(kind, (host, port), system_id, vehicle_component_id, on_message, tlog)
        await loop.create_datagram_endpoint(lambda: proto, local_addr=(host, 0))
    else:
        proto = MavlinkLink(kind, None, system_id, vehicle_component_id, on_message, tlog)
        await loop.create_datagram_endpoint(lambda: proto, local_addr=(host, port))
    return proto
