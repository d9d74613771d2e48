"""The asyncio UDP adapter of the ground-station endpoints (:mod:`mavreg.daemon.gcs.bridge`).

One non-blocking UDP socket per ``--gcs`` URL, watched with ``loop.add_reader``:

- ``udpout:HOST:PORT`` (QGroundControl and ``mavproxy.py --master udpin:...`` listen so):
  sends to HOST:PORT and accepts datagrams only from that address;
- ``udpin:HOST:PORT``: listens; the first address that sends a MAVLink frame becomes the
  ground station, other addresses are dropped and counted. Nothing is sent before that.

The hooks the daemon calls (:meth:`GcsLink.vehicle_message`, :meth:`GcsLink.daemon_output`,
:meth:`GcsLink.heartbeat`) only queue; one task (owned here, cancelled by :meth:`close`)
sends the queues every :data:`DRAIN_S` with non-blocking ``sendto`` (a full socket buffer
drops the datagram, counted). The clock is injected.
"""
from __future__ import annotations

import asyncio
import socket
import struct
from typing import Callable

from .bridge import GcsHub, GcsParams, parse_gcs_url

__all__ = ["GcsLink", "DRAIN_S"]

DRAIN_S = 0.02
"""Period of the task that sends the queued frames (50 Hz)."""
_MAX_DATAGRAM = 65535


class _Endpoint:
    def __init__(self, url: str, sock: socket.socket, peer):
        self.url = url
        self.sock = sock
        self.peer = peer
        self.fixed = peer is not None


class GcsLink:
    """Ground-station endpoints of one daemon.

    Parameters
    ----------
    urls : sequence of str
        ``udpout:HOST[:PORT]`` / ``udpin:HOST[:PORT]`` (port 14550 if omitted).
    system_id : int
        The vehicle's system id.
    params : GcsParams
    clock_s : callable
        Monotonic seconds (rate limits, token buckets).
    in_control : callable
        ``() -> bool``: the daemon is running a flight (:func:`mavreg.daemon.gcs.policy.judge`).
    to_vehicle : callable
        ``msg -> bool``: send an allowed ground-station message to the vehicle.
    request_land : callable
        ``() -> None``: the daemon's own land request.
    log : callable
        One line per endpoint opened.
    """

    def __init__(self, urls, system_id: int, params: GcsParams, clock_s: Callable[[], float],
                 in_control: Callable[[], bool], to_vehicle: Callable, request_land: Callable[[], None],
                 log: Callable[[str], None]):
        self.urls = tuple(urls)
        for url in self.urls:
            parse_gcs_url(url)
        self.hub = GcsHub(len(self.urls), params, system_id)
        self.clock_s = clock_s
        self.in_control = in_control
        self.to_vehicle = to_vehicle
        self.request_land = request_land
        self.log = log
        self.endpoints: list[_Endpoint] = []
        self._loop: asyncio.AbstractEventLoop | None = None
        self._task: asyncio.Task | None = None
        self._closed = False

    async def open(self) -> None:
        """Create every socket and the sending task; ValueError (one line) if one cannot be opened."""
        self._loop = asyncio.get_running_loop()
        for i, url in enumerate(self.urls):
            try:
                self.endpoints.append(_open_socket(url))
            except OSError as exc:           # unknown host, port in use: the user's mistake, one line
                self.close()
                raise OSError(f"--gcs {url!r}: {exc.strerror or exc}") from None
            self._loop.add_reader(self.endpoints[i].sock.fileno(), self._readable, i)
            ep = self.endpoints[i]
            where = (f"sending to {ep.peer[0]}:{ep.peer[1]}" if ep.fixed else
                     "listening on {}:{}".format(*ep.sock.getsockname()[:2]))
            self.log(f"ground station {url}: {where} "
                     f"({'commands allowed' if self.hub.params.allow_commands else 'read-only'})")
        self._task = asyncio.create_task(self._send_task(), name="gcs")

    # ------------------------------------------------------------------ hooks
    def vehicle_message(self, msg) -> None:
        self.hub.vehicle_message(msg, self.clock_s())

    def daemon_output(self, out) -> None:
        if out.events or out.messages:
            self.hub.daemon_output(out.messages, out.events, self.clock_s())

    def heartbeat(self, hb, phase: str) -> None:
        self.hub.heartbeat(hb, phase, self.clock_s())

    # ------------------------------------------------------------------ I/O
    def _readable(self, i: int) -> None:
        ep = self.endpoints[i]
        c = self.hub.endpoints[i].counters
        while not self._closed:
            try:
                data, addr = ep.sock.recvfrom(_MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:                  # e.g. ICMP port unreachable: no ground station yet
                c.send_errors += 1
                return
            if ep.peer is not None and tuple(addr[:2]) != ep.peer:
                c.foreign_address += 1
                continue
            bad = c.bad_data
            res = self.hub.receive(i, data, self.clock_s(), self.in_control())
            if ep.peer is None and c.bad_data == bad:
                ep.peer = tuple(addr[:2])
            for msg in res.forward:
                try:
                    self.to_vehicle(msg)
                except (ValueError, TypeError, NotImplementedError, struct.error):
                    c.send_errors += 1       # a message that cannot be packed again: dropped
            if res.land:
                self.request_land()

    async def _send_task(self) -> None:
        while True:
            await asyncio.sleep(DRAIN_S)
            self.flush()

    def flush(self) -> None:
        """Send what the token buckets allow now."""
        now = self.clock_s()
        for i, ep in enumerate(self.endpoints):
            c = self.hub.endpoints[i].counters
            if ep.peer is None:
                c.dropped_queue += len(self.hub.endpoints[i].queue)
                self.hub.endpoints[i].queue.clear()
                continue
            for data, frames in self.hub.drain(i, now):
                try:
                    ep.sock.sendto(data, ep.peer)
                except OSError:              # buffer full, unreachable: dropped, never waited for
                    c.send_errors += 1
                    continue
                c.datagrams_out += 1
                c.to_gcs += frames

    def status(self) -> list[dict]:
        return [dict(s, url=url) for s, url in zip(self.hub.status(), self.urls)]

    async def aclose(self) -> None:
        """:meth:`close`, then wait for the sending task to end."""
        self.close()
        if self._task is not None:
            await asyncio.gather(self._task, return_exceptions=True)

    def close(self) -> None:
        """Stop the task and close the sockets (idempotent)."""
        if self._closed:
            return
        self._closed = True
        if self._task is not None:
            self._task.cancel()
        for ep in self.endpoints:
            if self._loop is not None and not self._loop.is_closed():
                self._loop.remove_reader(ep.sock.fileno())
            ep.sock.close()


def _open_socket(url: str) -> _Endpoint:
    kind, host, port = parse_gcs_url(url)
    info = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
    sock = socket.socket(info[0], socket.SOCK_DGRAM)
    try:
        sock.setblocking(False)
        if kind == "udpout":           # any local address: the ground station may be remote
            peer = socket.getaddrinfo(host, port, family=info[0], type=socket.SOCK_DGRAM)[0][4][:2]
            sock.bind(("::" if info[0] == socket.AF_INET6 else "0.0.0.0", 0))
        else:
            sock.bind(info[4])
            peer = None
    except OSError:
        sock.close()
        raise
    return _Endpoint(url, sock, tuple(peer) if peer is not None else None)
