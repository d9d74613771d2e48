"""The ground-station options (``--gcs``, ``--gcs-allow-commands``): their parser and limits,
in a module of their own that imports no MAVLink, so that the command line checks them
before it imports the daemon (:mod:`mavreg.daemon.gcs.bridge` re-exports both)."""
from __future__ import annotations

import math
from dataclasses import dataclass

from ...transport.urls import parse_udp_url

__all__ = ["GCS_DEFAULT_PORT", "GcsParams", "parse_gcs_url"]

GCS_DEFAULT_PORT = 14550
"""The UDP port QGroundControl listens on, and MAVProxy's usual ground-station port."""


def parse_gcs_url(url: str) -> tuple[str, str, int]:
    """``udpout:HOST[:PORT]`` or ``udpin:HOST[:PORT]`` -> (kind, host, port); port 14550 if omitted
    (``udpin`` port 0: any free port, logged when opened).

    Raises ValueError with a one-line reason on anything else.
    """
    why = f"--gcs {url!r}: expected udpout:HOST[:PORT] or udpin:HOST[:PORT] (default port {GCS_DEFAULT_PORT})"
    return parse_udp_url(url, why, default_port=GCS_DEFAULT_PORT)


@dataclass(frozen=True)
class GcsParams:
    """Forwarding limits and the command policy of the ground-station endpoints."""

    allow_commands: bool = False
    """Forward the ground station's messages to the vehicle (:func:`judge`); default read-only."""
    stream_rate_hz: float = 20.0
    """Most messages of one streamed type per second, per endpoint (wall time)."""
    max_messages_per_s: float = 300.0
    """Token bucket of each endpoint: messages sent per second, on average..."""
    burst_messages: int = 100
    """...and at once."""
    queue_len: int = 256
    """Messages waiting for an endpoint; more are dropped and counted."""
    max_datagram_bytes: int = 1400
    """Frames are packed into datagrams of at most this size (one Ethernet MTU)."""
    notice_interval_s: float = 5.0
    """At most one STATUSTEXT per this many seconds explains refused messages to a ground station."""

    def __post_init__(self):
        for name in ("stream_rate_hz", "max_messages_per_s", "notice_interval_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"GcsParams.{name} must be a positive number, got {v}")
        if self.burst_messages < 1 or self.queue_len < 1 or self.max_datagram_bytes < 280:
            raise ValueError("GcsParams: burst_messages and queue_len must be >= 1, "
                             "max_datagram_bytes >= 280 (one MAVLink 2 frame)")
