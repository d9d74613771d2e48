"""The serial or TCP link to the vehicle: a byte stream <-> MAVLink 2 messages.

A thin adapter, as :class:`mavreg.daemon.vehicle.link.FastLink` is for UDP, whose frame handling it
shares: the tty or socket is read with ``loop.add_reader`` and ``os.read``
(:class:`mavreg.transport.tty.ByteStream`), the bytes go through the sans-I/O
:class:`mavreg.transport.framing.StreamFramer` (frames cut across reads joined, garbage and
broken frames skipped and counted under ``garbage_bytes`` and ``bad_data``), and the whole
frames of one read are handled as one datagram: the peer filter, the ``.tlog``, the
precompiled codec, the callback. What one output sends (a command and its TIMESYNC) is
written in one ``os.write``.

A stream has one peer by construction: the daemon sends nothing before the vehicle's first
autopilot HEARTBEAT, which names its system id (as on ``udpin:``), unless the id is pinned.
When the stream ends (a pseudo-terminal or a USB serial device gone, the TCP peer closed)
the link stops reading and says so once (``on_closed``); the supervisor then sees no
samples and hands the vehicle to its failsafe after ``--stale-timeout-s`` (link lost).
"""
from __future__ import annotations

import asyncio
import errno
from typing import Callable

from ...transport.framing import StreamFramer
from ...transport.tty import ByteStream, open_serial, tcp_socket
from .link import FastLink
from ..logs.tlog import TlogWriter
from .url import parse_url

__all__ = ["StreamLink", "open_stream_link", "TCP_CONNECT_TIMEOUT_S"]

TCP_CONNECT_TIMEOUT_S = 5.0


class StreamLink(FastLink):
    """MAVLink 2 over one byte stream, to one vehicle (see the module docstring).

    Parameters are those of :class:`FastLink` but the socket: the open ``stream``, its
    ``url``, and ``on_closed(line)`` told once when the stream ends.
    """

    def __init__(self, url: str, system_id: int | None, vehicle_component_id: int, on_message: Callable,
                 tlog: TlogWriter | None, stream: ByteStream, signing=None, on_closed: Callable | None = None,
                 on_read_end: Callable | None = None):
        super().__init__(parse_url(url)[0], None, system_id, vehicle_component_id, on_message, tlog, None, signing,
                         on_read_end)
        self.url = url
        self.stream = stream
        self.framer = StreamFramer()
        self.on_closed = on_closed
        self._addr = (url, 0)
        """The stream's one peer address, for the peer filter."""
        self._reading = False

    def start(self, loop: asyncio.AbstractEventLoop) -> None:
        self._loop = loop
        loop.add_reader(self.stream.fileno(), self._readable)
        self._reading = True

    def _readable(self) -> None:
        data = self.stream.read()
        if data is None:
            self._ended()
            return
        if not data:
            return
        fc = self.framer.counters
        bad0, garbage0 = fc.bad_frames, fc.garbage_bytes
        frames = self.framer.feed(data)
        self.counters.bad_data += fc.bad_frames - bad0
        self.counters.garbage_bytes += fc.garbage_bytes - garbage0
        if frames:
            self.datagram_received(frames, self._addr)
            if self.on_read_end is not None:
                self.on_read_end()

    def _ended(self) -> None:
        self._stop_reading()
        if self.on_closed is not None and not self._closed:
            self.on_closed(f"link: {self.stream.closed_reason}: no more telemetry from the vehicle")

    def _stop_reading(self) -> None:
        if self._reading and self._loop is not None and not self._loop.is_closed():
            self._loop.remove_reader(self.stream.fileno())
        self._reading = False

    def _transmit(self, data: bytes) -> bool:
        return self.stream.write(data)

    def close(self) -> None:
        if self._closed:
            return
        self._stop_reading()
        self._closed = True
        self.stream.close()
        if self.signing is not None:
            self.signing.save()


async def open_stream_link(url: str, system_id: int | None, vehicle_component_id: int, on_message: Callable,
                           tlog: TlogWriter | None, signing=None, on_closed: Callable | None = None,
                           on_read_end: Callable | None = None) -> StreamLink:
    """Open ``serial:PATH[:BAUD]`` (raw, at the baud) or connect ``tcp:HOST:PORT`` (within
    :data:`TCP_CONNECT_TIMEOUT_S`), and start reading; OSError with a one-line reason naming
    the device or the address."""
    kind, where, number = parse_url(url)
    loop = asyncio.get_running_loop()
    if kind == "serial":
        stream = ByteStream(open_serial(where, number), url)
    else:
        sock, addr = tcp_socket(where, number)
        try:
            await asyncio.wait_for(loop.sock_connect(sock, addr), TCP_CONNECT_TIMEOUT_S)
        except (OSError, asyncio.TimeoutError) as exc:
            sock.close()
            why = getattr(exc, "strerror", None) or f"no answer within {TCP_CONNECT_TIMEOUT_S:g} s"
            raise OSError(getattr(exc, "errno", None) or errno.ETIMEDOUT, f"tcp {where}:{number}: {why}") from None
        stream = ByteStream(sock.fileno(), url, owner=sock)
    link = StreamLink(url, system_id, vehicle_component_id, on_message, tlog, stream, signing, on_closed, on_read_end)
    link.start(loop)
    return link
