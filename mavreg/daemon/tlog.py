"""MAVLink telemetry log in pymavlink's ``.tlog`` format.

Each record is an 8-byte big-endian unsigned timestamp (microseconds since the Unix
epoch) followed by the raw bytes of one MAVLink message, exactly as it went over the
wire. ``mavlogdump.py``, MAVProxy and ``mavutil.mavlink_connection(path)`` read it.
Messages in and out are both logged; the writer is buffered and flushed on close.
A SETUP_SIGNING frame (it carries a signing key) is never written, whichever way it went.
"""
from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import Callable

__all__ = ["TlogWriter"]

_TS = struct.Struct(">Q")
_SETUP_SIGNING = 256


def _carries_key(frame) -> bool:
    """A MAVLink 2 SETUP_SIGNING frame (MAVLink 1 cannot carry message ids above 255)."""
    return len(frame) >= 10 and frame[0] == 0xFD and (frame[7] | (frame[8] << 8) | (frame[9] << 16)) == _SETUP_SIGNING


class TlogWriter:
    """Append MAVLink message bytes with a timestamp.

    Parameters
    ----------
    path : path-like
        File to create (truncated if it exists).
    clock_s : callable, optional
        Wall clock in seconds since the epoch (injected for tests); ``time.time`` by default.
    """

    def __init__(self, path: str | Path, clock_s: Callable[[], float] | None = None):
        self.path = Path(path)
        self._clock = time.time if clock_s is None else clock_s
        self._f = open(self.path, "wb", buffering=1 << 16)
        self.count = 0

    def write(self, msgbuf: bytes) -> None:
        """Log one message's wire bytes (one MAVLink frame)."""
        if self._f.closed or _carries_key(msgbuf):
            return
        self._f.write(_TS.pack(int(self._clock() * 1e6)) + bytes(msgbuf))
        self.count += 1

    def write_many(self, frames) -> None:
        """Log frames that went over the wire together (one datagram): one time stamp, one write."""
        frames = [f for f in frames if not _carries_key(f)]
        if self._f.closed or not frames:
            return
        ts = _TS.pack(int(self._clock() * 1e6))
        self._f.write(b"".join(ts + bytes(f) for f in frames))
        self.count += len(frames)

    def close(self) -> None:
        if not self._f.closed:
            self._f.close()

    def __enter__(self) -> "TlogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
