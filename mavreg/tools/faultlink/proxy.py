"""An asyncio UDP proxy that puts a :class:`~.model.FaultLine` in each direction.

The daemon talks to the proxy's listening address as if it were the vehicle
(``--vehicle udpout:HOST:LISTEN_PORT``); the proxy forwards every datagram to the vehicle
through the *up* line and every datagram of the vehicle to the daemon (the last address
the daemon sent from) through the *down* line. A datagram is one item: it is lost,
delayed, reordered, duplicated or corrupted whole. Times are wall-clock seconds since the
proxy started (outages included), on the loop's monotonic clock.
"""
from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

from .model import FaultLine, FaultParams

__all__ = ["FaultProxy", "start_proxy"]


class _Side(asyncio.DatagramProtocol):
    def __init__(self, on_datagram):
        self.on_datagram = on_datagram
        self.transport = None

    def connection_made(self, transport):
        self.transport = transport

    def datagram_received(self, data, addr):
        self.on_datagram(data, addr)

    def error_received(self, exc):            # e.g. ICMP port unreachable: the peer is gone for now
        pass


@dataclass
class FaultProxy:
    """The running proxy: its two lines and sockets (see :func:`start_proxy`)."""

    up: FaultLine
    down: FaultLine
    vehicle_addr: tuple
    loop: asyncio.AbstractEventLoop
    t0: float
    daemon_addr: tuple | None = None
    listen_addr: tuple = ()
    _sides: dict = field(default_factory=dict)
    _timers: dict = field(default_factory=dict)

    def now_s(self) -> float:
        return self.loop.time() - self.t0

    def _from_daemon(self, data: bytes, addr) -> None:
        self.daemon_addr = addr
        self.up.push(self.now_s(), data)
        self._arm("up")

    def _from_vehicle(self, data: bytes, addr) -> None:
        if tuple(addr[:2]) != tuple(self.vehicle_addr[:2]):
            return                                       # only the vehicle speaks on this side
        self.down.push(self.now_s(), data)
        self._arm("down")

    def _arm(self, name: str) -> None:
        """(Re)schedule the release of ``name``'s next due datagram."""
        line = self.up if name == "up" else self.down
        due = line.next_due()
        old = self._timers.get(name)
        if due is None or (old is not None and old[0] <= due):
            return
        if old is not None:
            old[1].cancel()
        self._timers[name] = (due, self.loop.call_at(self.t0 + due, self._release, name))

    def _release(self, name: str) -> None:
        self._timers.pop(name, None)
        if name == "up":
            for data in self.up.pop_due(self.now_s()):
                self._sides["vehicle"].transport.sendto(data, self.vehicle_addr)
        else:
            for data in self.down.pop_due(self.now_s()):
                if self.daemon_addr is not None:
                    self._sides["daemon"].transport.sendto(data, self.daemon_addr)
        self._arm(name)

    def close(self) -> None:
        for _, handle in self._timers.values():
            handle.cancel()
        for side in self._sides.values():
            if side.transport is not None:
                side.transport.close()


async def start_proxy(listen: tuple[str, int], vehicle: tuple[str, int], up: FaultParams,
                      down: FaultParams) -> FaultProxy:
    """Bind ``listen`` for the daemon and an ephemeral port towards ``vehicle``; return the proxy.

    ``up`` faults datagrams daemon -> vehicle, ``down`` vehicle -> daemon. Port 0 in
    ``listen`` picks a free port (``proxy.listen_addr`` has the one bound).
    """
    loop = asyncio.get_running_loop()
    proxy = FaultProxy(FaultLine(up, "up"), FaultLine(down, "down"), tuple(vehicle), loop, loop.time())
    d_tr, d_side = await loop.create_datagram_endpoint(lambda: _Side(proxy._from_daemon), local_addr=listen)
    v_tr, v_side = await loop.create_datagram_endpoint(lambda: _Side(proxy._from_vehicle),
                                                       local_addr=(listen[0], 0))
    proxy._sides = {"daemon": d_side, "vehicle": v_side}
    proxy.listen_addr = d_tr.get_extra_info("sockname")[:2]
    return proxy
