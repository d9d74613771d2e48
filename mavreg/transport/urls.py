"""Stream URLs: ``serial:PATH[:BAUD]``, ``tcp:HOST:PORT`` (client), ``tcpin:HOST:PORT`` (server).

The serial form is the one pymavlink and MAVProxy take after ``--master`` (``/dev/ttyACM0,921600``
there; a colon here, as MAVSDK's ``serial:///dev/ttyACM0:921600``): the device path, then the
baud, :data:`DEFAULT_BAUD` when left out. A path never holds a colon here (Linux device names
do not), so the last field is the baud when it is a number.
"""
from __future__ import annotations

from typing import NamedTuple

__all__ = ["StreamUrl", "parse_stream_url", "DEFAULT_BAUD", "STREAM_KINDS", "STREAM_FORMS"]

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
