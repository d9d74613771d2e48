"""Stream URLs: ``serial:PATH[:BAUD]``, ``tcp:HOST:PORT`` (client), ``tcpin:HOST:PORT`` (server).

The serial form is the one pymavlink and MAVProxy take after ``--master`` (``/dev/ttyACM0,921600``
there; a colon here, as MAVSDK's ``serial:///dev/ttyACM0:921600``): the device path, then the
baud, :data:`DEFAULT_BAUD` when left out. A path never holds a colon here (Linux device names
do not), so the last field is the baud when it is a number.
"""
from __future__ import annotations

from typing import NamedTuple

__all__ = ["StreamUrl", "parse_stream_url", "parse_udp_url", "DEFAULT_BAUD", "STREAM_KINDS", "STREAM_FORMS"]

DEFAULT_BAUD = 921600
"""The usual companion-computer UART speed (PX4 ``SER_TEL2_BAUD``, ArduPilot ``SERIAL2_BAUD`` 921)."""
STREAM_KINDS = ("serial", "tcp", "tcpin")
STREAM_FORMS = {"serial": "serial:PATH[:BAUD] (baud 921600 if left out)", "tcp": "tcp:HOST:PORT",
                "tcpin": "tcpin:HOST:PORT"}


class StreamUrl(NamedTuple):
    kind: str
    """``serial``, ``tcp`` or ``tcpin``."""
    where: str
    """The device path (serial) or the host (tcp, tcpin)."""
    number: int
    """The baud (serial, bits per second) or the port (tcp, tcpin)."""

    @property
    def baud_bps(self) -> int | None:
        """The line's speed in bits per second (a serial port), None for TCP."""
        return self.number if self.kind == "serial" else None

    def __str__(self) -> str:
        return f"{self.kind}:{self.where}:{self.number}"


def parse_udp_url(url: str, why: str, default_port: int | None = None) -> tuple[str, str, int]:
    """``udpin:HOST:PORT`` or ``udpout:HOST:PORT`` -> (kind, host, port); the port may be left out
    where there is a ``default_port``, and is 0 (any free port) only on ``udpin``. Raises
    ValueError with ``why`` (the option and its forms), and what is wrong, in one line.

    >>> parse_udp_url("udpout:127.0.0.1", "--gcs", default_port=14550)
    ('udpout', '127.0.0.1', 14550)
    """
    parts = url.split(":")
    if default_port is not None and len(parts) == 2:
        parts.append(str(default_port))
    if len(parts) != 3 or parts[0] not in ("udpin", "udpout") or not parts[1]:
        raise ValueError(why)
    try:
        port = int(parts[2])
    except ValueError:
        raise ValueError(f"{why}; port {parts[2]!r} is not a number") from None
    if not 0 <= port <= 65535 or (parts[0] == "udpout" and port == 0):
        raise ValueError(f"{why}; port {port} out of range")
    return parts[0], parts[1], port


def parse_stream_url(url: str, kinds=STREAM_KINDS, option: str = "vehicle URL") -> StreamUrl:
    """``url`` as a :class:`StreamUrl` of one of ``kinds``; ValueError with a one-line reason
    (naming ``option``) on anything else. A ``tcpin`` port may be 0 (a free one)."""
    kind, _, rest = url.partition(":")
    if kind not in kinds:
        raise ValueError(f"{option} {url!r}: expected {' or '.join(STREAM_FORMS[k] for k in kinds)}")
    if kind == "serial":
        path, sep, last = rest.rpartition(":")
        if not sep or not last.isdigit():
            path, last = rest, str(DEFAULT_BAUD)
        if not path.startswith("/") or ":" in path:
            raise ValueError(f"{option} {url!r}: expected serial:PATH[:BAUD] with an absolute device "
                             "path, e.g. serial:/dev/ttyACM0:921600")
        baud = int(last)
        if baud <= 0:
            raise ValueError(f"{option} {url!r}: the baud must be positive")
        return StreamUrl(kind, path, baud)
    host, sep, port_text = rest.rpartition(":")
    if not sep or not host:
        raise ValueError(f"{option} {url!r}: expected {STREAM_FORMS[kind]}")
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"{option} {url!r}: port {port_text!r} is not a number") from None
    if not (0 if kind == "tcpin" else 1) <= port <= 65535:
        raise ValueError(f"{option} {url!r}: port out of range")
    return StreamUrl(kind, host, port)
