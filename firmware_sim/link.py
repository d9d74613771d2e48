"""UDP socket plus a MAVLink 2 codec (no blocking mavutil connection).

Received messages pass :class:`firmware_sim.peers.PeerFilter` (configured peer systems,
their component and address learned from their HEARTBEAT; with a signing key, validly
signed and not replayed, :mod:`mavreg.transport.signing`); telemetry goes to the learned
peers' addresses only, signed when signing is on. Each datagram is parsed on its own: bytes of a datagram that do not form a complete message are counted
as malformed and discarded, so one peer's garbage never corrupts another's message.

Everything one :meth:`Link.send` is given (a control period's telemetry bundle, or the
replies to a command) leaves in **one** datagram per peer, as PX4 fills its network
buffer and flushes it once per loop (datagrams stay under :data:`MAX_DATAGRAM_BYTES`);
the hot messages are packed and parsed by the precompiled codec of
:mod:`mavreg.transport.wire`. With ``MAVREG_IO=reference`` in the environment the link
works as it did before (one message per datagram, pymavlink's codec, sequence number
always 0): the benchmarks' baseline.
"""
from __future__ import annotations

import os
import select
import socket

from pymavlink.dialects.v20 import common as mavlink2

from .peers import PeerFilter
from mavreg.transport.wire import Wire

__all__ = ["Link", "open_link", "is_stream_url", "LISTEN_FORMS", "parse_listen_url", "parse_remote_url", "MAX_DATAGRAM_BYTES", "io_impl"]

MAX_DATAGRAM_BYTES = 1400
"""Frames are packed together into datagrams up to this size (an Ethernet MTU with room)."""
_MAX_DATAGRAM = 65535
IO_ENV = "MAVREG_IO"


def _as_is(frame: bytes) -> bytes:
    return frame


def io_impl() -> str:
    """``fast`` (default) or ``reference``, from the ``MAVREG_IO`` environment variable.

    Raises
    ------
    ValueError
        For any other value.
    """
    impl = os.environ.get(IO_ENV, "fast")
    if impl not in ("fast", "reference"):
        raise ValueError(f"{IO_ENV}={impl!r}: expected 'fast' or 'reference'")
    return impl


def _parse_url(url: str, option: str, wanted: str, lowest_port: int) -> tuple[str, int]:
    """``WANTED:HOST:PORT`` -> ``(host, port)``, the port in ``lowest_port``..65535; else
    ValueError naming ``option``."""
    scheme, _, rest = url.partition(":")
    host, sep, port_text = rest.rpartition(":")
    if scheme != wanted or not sep or not host:
        raise ValueError(f"{option} {url!r}: expected {wanted}:HOST:PORT (e.g. {wanted}:127.0.0.1:14540)")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"{option} {url!r}: port must be an integer") from None
    if not lowest_port <= port <= 65535:
        raise ValueError(f"{option} {url!r}: port must be in {lowest_port}..65535")
    return host, port


LISTEN_FORMS = "udpin:HOST:PORT, pty, serial:PATH[:BAUD] or tcpin:HOST:PORT"


def parse_listen_url(url: str):
    """``udpin:HOST:PORT`` -> ``(host, port)``, port 0 picking a free port; ``pty``,
    ``serial:PATH[:BAUD]``, ``tcpin:HOST:PORT``: :func:`firmware_sim.stream_link.parse_stream_listen_url`.

    Raises
    ------
    ValueError
        For anything else.
    """
    if is_stream_url(url):
        from .stream_link import parse_stream_listen_url
        return parse_stream_listen_url(url)
    if not url.startswith("udpin:"):
        raise ValueError(f"--listen {url!r}: expected {LISTEN_FORMS}")
    return _parse_url(url, "--listen", "udpin", 0)


def is_stream_url(url: str) -> bool:
    """Whether ``--listen url`` is a byte stream (:mod:`firmware_sim.stream_link`)."""
    return url == "pty" or url.split(":", 1)[0] in ("serial", "tcpin")


def open_link(url: str, system_id: int, component_id: int, **kwargs):
    """A :class:`Link` (UDP) or a :class:`firmware_sim.stream_link.StreamLink` for ``url``."""
    if is_stream_url(url):
        from .stream_link import StreamLink
        return StreamLink(url, system_id, component_id, **kwargs)
    if kwargs.pop("byte_loss", 0.0):
        raise ValueError(f"--serial-byte-loss applies to a pty, serial or tcpin --listen, not to {url!r}")
    kwargs.pop("seed", None)
    return Link(url, system_id, component_id, **kwargs)


def parse_remote_url(url: str) -> tuple[str, int]:
    """``udpout:HOST:PORT`` (``--remote``) -> ``(host, port)``, a port in 1..65535.

    Raises
    ------
    ValueError
        For anything else.
    """
    return _parse_url(url, "--remote", "udpout", 1)


class Link:
    """A bound, non-blocking UDP socket speaking MAVLink 2.

    Parameters
    ----------
    url : str
        ``udpin:HOST:PORT``.
    system_id, component_id : int
        Our identity in every message sent.
    io : {"fast", "reference"}, optional
        Default: :func:`io_impl`.
    peer_system_ids : iterable of int, optional
        Systems whose messages are taken (default: ours, the daemon's).
    signing : Signing or None
    remote : (host, port) or None
        Also sent to from the start (``--remote``), before anything is heard from it.
    """

    def __init__(self, url: str, system_id: int, component_id: int, io: str | None = None,
                 peer_system_ids=None, signing=None, remote=None):
        host, port = parse_listen_url(url)
        self.fast = (io_impl() if io is None else io) == "fast"
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise ValueError(f"--listen {url!r}: cannot bind: {exc.strerror or exc}") from None
        self.sock.setblocking(False)
        self.host, self.port = self.sock.getsockname()[:2]
        self.wire = Wire(system_id, component_id)
        self.mav = self.wire.mav                      # the reference codec (robust parsing)
        self.signing = signing
        self.filter = PeerFilter(system_id, component_id,
                                 (system_id,) if peer_system_ids is None else peer_system_ids, signing,
                                 None if remote is None else self._resolve(remote))
        self.peers: list = self.filter.addresses
        """The learned peers' addresses (the filter keeps this list)."""
        self.bytes_in = 0
        self.send_errors = 0

    def _resolve(self, remote) -> tuple[str, int]:
        """``remote``'s address as ``recvfrom`` reports it (a host name resolved once)."""
        try:
            info = socket.getaddrinfo(remote[0], remote[1], socket.AF_INET, socket.SOCK_DGRAM)
        except OSError as exc:
            self.sock.close()
            raise ValueError(f"--remote {remote[0]}:{remote[1]}: {exc.strerror or exc}") from None
        return info[0][4][:2]

    @property
    def url(self) -> str:
        """The URL actually bound (with the real port)."""
        return f"udpin:{self.host}:{self.port}"

    def _reset_parser(self) -> None:
        self.mav.buf = bytearray()
        self.mav.buf_index = 0
        self.mav.expected_length = mavlink2.HEADER_LEN_V1 + 2

    def recv_datagram(self):
        """Read one datagram: ``(messages, addr)``, or ``None`` when none is waiting.

        ``messages`` may contain ``BAD_DATA`` objects (malformed bytes, CRC failures,
        unknown ids, truncated tails); the autopilot counts them.
        """
        try:
            data, addr = self.sock.recvfrom(_MAX_DATAGRAM)
        except (BlockingIOError, InterruptedError):
            return None
        except OSError:          # e.g. ICMP port unreachable reported on Linux
            return [], None
        self.bytes_in += len(data)
        try:
            msgs = self.wire.parse(data) if self.fast else (self.mav.parse_buffer(data) or [])
        except Exception as exc:  # pymavlink raises on some corrupt input even when robust
            msgs = [mavlink2.MAVLink_bad_data(bytearray(data), str(exc))]
            self._reset_parser()
        if self.mav.buf_len() > 0:
            msgs.append(mavlink2.MAVLink_bad_data(bytearray(self.mav.buf[self.mav.buf_index:]), "truncated"))
            self._reset_parser()
        return self.filter.admit(msgs, addr), addr

    def send(self, msgs) -> None:
        """Pack each message once and send them all to every peer, in one datagram each."""
        if not msgs or not self.peers:
            return
        sign = self.signing.sign if self.signing is not None else _as_is
        if not self.fast:
            datagrams = [sign(m.pack(self.mav)) for m in msgs]
        else:
            pack = self.wire.pack
            frames = [sign(pack(m)) for m in msgs]
            if len(frames) == 1:
                datagrams = frames
            else:
                datagrams, cur = [], b""
                for f in frames:
                    if cur and len(cur) + len(f) > MAX_DATAGRAM_BYTES:
                        datagrams.append(cur)
                        cur = b""
                    cur += f
                datagrams.append(cur)
        sendto = self.sock.sendto
        for buf in datagrams:
            for addr in self.peers:
                try:
                    sendto(buf, addr)
                except OSError:
                    self.send_errors += 1

    def wait_readable(self, timeout_s: float) -> bool:
        """Block until a datagram is waiting or ``timeout_s`` passes."""
        if timeout_s <= 0:
            timeout_s = 0.0
        r, _, _ = select.select([self.sock], [], [], timeout_s)
        return bool(r)

    def close(self) -> None:
        self.sock.close()
        if self.signing is not None:
            self.signing.save()
