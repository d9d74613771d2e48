"""The emulator's serial and TCP links: a pseudo-terminal, a serial device or a TCP server.

``--listen pty`` makes a new pseudo-terminal pair, keeps both ends (so that the master never
reads EIO while nobody has the slave open) and announces the slave as
``serial:/dev/pts/N``: what a flight controller's TELEM port is to a companion computer.
``--listen serial:PATH[:BAUD]`` opens an existing device; ``--listen tcpin:HOST:PORT``
listens for one TCP client at a time (ArduPilot SITL's ``tcp:5760``; a second client is
refused while one is connected, a new one is taken once it has gone).

A stream is one peer by construction: the vehicle speaks first, sending to it from the
start as a flight controller sends on its serial port (``--remote`` on UDP), and the peer
filter (:mod:`firmware_sim.peers`) then takes its peer's frames by HEARTBEAT as on UDP. The
bytes go through :class:`mavreg.transport.framing.StreamFramer`: frames cut across reads
are joined, and each start of a frame that came to nothing (a lost or corrupted byte)
reaches the autopilot as one ``BAD_DATA`` (counted ``malformed``). The interface is
:class:`firmware_sim.link.Link`'s: one read is handled as one datagram.
"""
from __future__ import annotations

import select
import time

from pymavlink.dialects.v20 import common as mavlink2

from mavreg.tools.faultlink.model import ByteLoss
from mavreg.transport.framing import StreamFramer
from mavreg.transport.tty import ByteStream, open_pty, open_serial, tcp_socket
from mavreg.transport.urls import parse_stream_url

from .peers import PeerFilter
from mavreg.transport.wire import Wire

__all__ = ["StreamLink", "parse_stream_listen_url"]


def parse_stream_listen_url(url: str):
    """``pty``, ``serial:PATH[:BAUD]`` or ``tcpin:HOST:PORT`` -> :class:`StreamUrl` (``pty``: kind
    ``pty``); ValueError naming ``--listen`` otherwise."""
    if url == "pty":
        return ("pty", "", 0)
    return parse_stream_url(url, ("serial", "tcpin"), option="--listen")


class StreamLink:
    """A byte-stream link speaking MAVLink 2 (see the module docstring); the parameters are
    :class:`firmware_sim.link.Link`'s (``io`` and ``remote`` do not apply: a stream is sent to
    from the start), and ``byte_loss``: each byte lost with that probability each way, from
    ``seed`` (:class:`mavreg.tools.faultlink.ByteLoss`; ``--serial-byte-loss``)."""

    def __init__(self, url: str, system_id: int, component_id: int, io: str | None = None,
                 peer_system_ids=None, signing=None, remote=None, byte_loss: float = 0.0, seed: int = 0):
        kind, where, number = parse_stream_listen_url(url)
        if remote is not None:
            raise ValueError(f"--remote applies to a udpin: --listen, not to {url!r} (a stream is sent to from "
                             "the start)")
        self.kind = kind
        self.stream: ByteStream | None = None
        self.server = None
        try:
            if kind == "pty":
                master, slave, path = open_pty()
                self.url = f"serial:{path}"
                self.stream = ByteStream(master, self.url, keep=(slave,))
            elif kind == "serial":
                self.url = url
                self.stream = ByteStream(open_serial(where, number), url)
            else:
                self.server, addr = tcp_socket(where, number)
                self.server.bind(addr)
                self.server.listen(1)
                host, port = self.server.getsockname()[:2]
                self.url = f"tcpin:{host}:{port}"
        except OSError as exc:
            if self.server is not None:
                self.server.close()
            raise ValueError(f"--listen {url!r}: {exc.strerror or exc}") from None
        self.wire = Wire(system_id, component_id)
        self.mav = self.wire.mav
        self.signing = signing
        self.framer = StreamFramer()
        self.addr = (self.url, 0)
        peers = (system_id,) if peer_system_ids is None else peer_system_ids
        self.filter = PeerFilter(system_id, component_id, peers, signing,
                                 self.addr if self.stream is not None else None)
        self.peers: list = self.filter.addresses
        self.bytes_in = 0
        self.send_errors = 0
        self.line = ({"up": ByteLoss(byte_loss, seed, "up"), "down": ByteLoss(byte_loss, seed, "down")}
                     if byte_loss > 0 else None)
        """The line's byte loss each way (None: a clean line)."""

    # ------------------------------------------------------------------ TCP server
    def _accept(self) -> None:
        """Take a waiting TCP client if none is connected (refuse it otherwise)."""
        try:
            conn, client = self.server.accept()
        except (BlockingIOError, InterruptedError):
            return
        if self.stream is not None:
            conn.close()
            return
        conn.setblocking(False)
        self.stream = ByteStream(conn.fileno(), self.url, owner=conn)
        self.framer = StreamFramer()
        self.addr = tuple(client[:2])
        self.filter.remote = self.addr
        self.filter.addresses[:] = [self.addr]

    def _client_gone(self) -> None:
        self.stream.close()
        self.stream = None
        self.filter.remote = None
        self.filter.addresses[:] = []
        self.filter.peers.clear()

    # ------------------------------------------------------------------ the Link interface
    def recv_datagram(self):
        """Read what is waiting: ``(messages, addr)``, or None when nothing was."""
        if self.server is not None:
            self._accept()
        if self.stream is None:
            return None
        data = self.stream.read()
        if data is None:
            if self.server is not None:
                self._client_gone()
            return None
        if not data:
            return None
        self.bytes_in += len(data)
        if self.line is not None:
            data = self.line["up"].apply(data)
        bad0 = self.framer.counters.bad_frames
        frames = self.framer.feed(data)
        msgs = self.wire.parse(frames) if frames else []
        msgs.extend(mavlink2.MAVLink_bad_data(bytearray(), "stream: not a valid frame")
                    for _ in range(self.framer.counters.bad_frames - bad0))
        return self.filter.admit(msgs, self.addr), self.addr

    def send(self, msgs) -> None:
        """Pack the messages and write them in one go, once the stream has a peer."""
        if not msgs or not self.peers or self.stream is None:
            return
        pack = self.wire.pack
        frames = [pack(m) for m in msgs]
        if self.signing is not None:
            frames = [self.signing.sign(f) for f in frames]
        data = b"".join(frames)
        if self.line is not None:
            data = self.line["down"].apply(data)
        if not self.stream.write(data):
            self.send_errors += 1

    def wait_readable(self, timeout_s: float) -> bool:
        """Block until bytes (or a TCP client) are waiting or ``timeout_s`` passes."""
        timeout_s = max(timeout_s, 0.0)
        watched = [s for s in (self.server, self.stream) if s is not None and s.fileno() >= 0]
        if self.stream is not None and self.stream.closed_reason is not None:
            watched.remove(self.stream)
        if not watched:
            time.sleep(timeout_s)
            return False
        r, _, _ = select.select(watched, [], [], timeout_s)
        return bool(r)

    def close(self) -> None:
        if self.stream is not None:
            self.stream.close()
        if self.server is not None:
            self.server.close()
        if self.signing is not None:
            self.signing.save()
