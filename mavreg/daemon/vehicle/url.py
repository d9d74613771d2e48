"""The vehicle's URL (``--vehicle``): its forms, parsed, and what each implies (no I/O)."""
from __future__ import annotations

from ...transport.urls import parse_stream_url, parse_udp_url

__all__ = ["parse_url", "VEHICLE_URL_FORMS", "STREAM_KINDS", "learns_system_id"]

VEHICLE_URL_FORMS = ("udpin:HOST:PORT, udpout:HOST:PORT, serial:PATH[:BAUD] (baud 921600 if left out) "
                     "or tcp:HOST:PORT")
"""The forms of ``--vehicle``, for messages and ``--help``."""
STREAM_KINDS = ("serial", "tcp")
"""Byte-stream links (:mod:`mavreg.daemon.vehicle.stream_link`): one peer by construction."""


def parse_url(url: str) -> tuple[str, str, int]:
    """``udpin:HOST:PORT``, ``udpout:HOST:PORT``, ``serial:PATH[:BAUD]`` or ``tcp:HOST:PORT`` ->
    (kind, host or device path, port or baud; :mod:`mavreg.transport.urls` for the streams).

    Raises ValueError with a one-line reason on anything else.
    """
    if url.split(":", 1)[0] in STREAM_KINDS:
        return tuple(parse_stream_url(url, STREAM_KINDS))
    return parse_udp_url(url, f"vehicle URL {url!r}: expected {VEHICLE_URL_FORMS}")


def learns_system_id(url: str | None) -> bool:
    """Whether the daemon waits for the vehicle to speak first and takes its system id from its
    first autopilot HEARTBEAT: ``udpin:`` and the streams (the vehicle's own port; a serial
    line or a TCP connection has one peer), not ``udpout:`` or the bundled emulator (None)."""
    return url is not None and url.split(":", 1)[0] in ("udpin", *STREAM_KINDS)
