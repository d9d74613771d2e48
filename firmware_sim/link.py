"""UDP socket plus pymavlink's MAVLink 2 codec (no blocking mavutil connection).

Telemetry goes to every address a valid MAVLink message came from. Each datagram is
parsed on its own: bytes of a datagram that do not form a complete message are counted
as malformed and discarded, so one peer's garbage never corrupts another's message.
"""
from __future__ import annotations

import select
import socket

from pymavlink.dialects.v20 import common as mavlink2

__all__ = ["Link", "parse_listen_url", "MAX_PEERS"]

MAX_PEERS = 8
_MAX_DATAGRAM = 65535


def parse_listen_url(url: str) -> tuple[str, int]:
    """``udpin:HOST:PORT`` -> ``(host, port)``; port 0 picks a free port.

    Raises
    ------
    ValueError
        For anything else.
    """
    scheme, _, rest = url.partition(":")
    host, sep, port_text = rest.rpartition(":")
    if scheme != "udpin" or not sep or not host:
        raise ValueError(f"--listen {url!r}: expected udpin:HOST:PORT (e.g. udpin:127.0.0.1:14540)")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"--listen {url!r}: port must be an integer") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"--listen {url!r}: port must be in 0..65535")
    return host, port


class Link:
    """A bound, non-blocking UDP socket speaking MAVLink 2.

    Parameters
    ----------
    url : str
        ``udpin:HOST:PORT``.
    system_id, component_id : int
        Our identity in every message sent.
    """

    def __init__(self, url: str, system_id: int, component_id: int):
        host, port = parse_listen_url(url)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.sock.bind((host, port))
        except OSError as exc:
            self.sock.close()
            raise ValueError(f"--listen {url!r}: cannot bind: {exc.strerror or exc}") from None
        self.sock.setblocking(False)
        self.host, self.port = self.sock.getsockname()[:2]
        self.mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.peers: list = []
        self.bytes_in = 0
        self.send_errors = 0

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
            msgs = self.mav.parse_buffer(data) or []
        except Exception as exc:  # pymavlink raises on some corrupt input even when robust
            msgs = [mavlink2.MAVLink_bad_data(bytearray(data), str(exc))]
            self._reset_parser()
        if self.mav.buf_len() > 0:
            msgs.append(mavlink2.MAVLink_bad_data(bytearray(self.mav.buf[self.mav.buf_index:]), "truncated"))
            self._reset_parser()
        if addr not in self.peers and any(m.get_type() != "BAD_DATA" for m in msgs):
            if len(self.peers) >= MAX_PEERS:
                self.peers.pop(0)
            self.peers.append(addr)
        return msgs, addr

    def send(self, msgs) -> None:
        """Pack each message once and send it to every peer."""
        if not msgs or not self.peers:
            return
        for m in msgs:
            buf = m.pack(self.mav)
            for addr in self.peers:
                try:
                    self.sock.sendto(buf, addr)
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
