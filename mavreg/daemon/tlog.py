"""MAVLink telemetry log in pymavlink's ``.tlog`` format.

Each record is an 8-byte big-endian unsigned timestamp (microseconds since the Unix
epoch) followed by the raw bytes of one MAVLink message, exactly as it went over the
wire. ``mavlogdump.py``, MAVProxy and ``mavutil.mavlink_connection(path)`` read it.
Messages in and out are both logged; the writer is buffered and flushed on close.
A SETUP_SIGNING frame (it carries a signing key) is never written, whichever way it went.

The timestamps come from an injected clock: the wall clock for a vehicle in real time,
:class:`VehicleClock` for a lockstep simulator, whose flight runs faster (or slower) than
the wall clock: there the log spans the flight's own (vehicle) time, so that log tools
(MAVExplorer, ``mavflightmodes.py``) show its real durations.
"""
from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import Callable

__all__ = ["TlogWriter", "VehicleClock"]

_TS = struct.Struct(">Q")
_SETUP_SIGNING = 256


def _carries_key(frame) -> bool:
    """A MAVLink 2 SETUP_SIGNING frame (MAVLink 1 cannot carry message ids above 255)."""
    return len(frame) >= 10 and frame[0] == 0xFD and (frame[7] | (frame[8] << 8) | (frame[9] << 16)) == _SETUP_SIGNING


class VehicleClock:
    """Seconds since the epoch that advance with the vehicle's clock.

    ``wall_s()`` when created, plus the vehicle time elapsed since the first reading of
    ``vehicle_time_s`` (None until the vehicle's first sample: the start time until then).
    The result never goes back (a vehicle clock that restarts holds it still).

    Parameters
    ----------
    vehicle_time_s : callable
        ``() -> float | None``: the vehicle's time of its latest sample (s), None before one.
    wall_s : callable, optional
        Wall clock in seconds since the epoch, read once (``time.time`` by default).
    """

    def __init__(self, vehicle_time_s: Callable[[], float | None],
                 wall_s: Callable[[], float] = time.time):
        self._vehicle = vehicle_time_s
        self._epoch_s = float(wall_s())
        self._first_s: float | None = None
        self._last_s = self._epoch_s

    def __call__(self) -> float:
        t = self._vehicle()
        if t is None:
            return self._last_s
        if self._first_s is None:
            self._first_s = t
        now = self._epoch_s + (t - self._first_s)
        if now > self._last_s:
            self._last_s = now
        return self._last_s


class TlogWriter:
    """Append MAVLink message bytes with a timestamp.

    Parameters
    ----------
    path : path-like
        File to create (truncated if it exists).
    clock_s : callable, optional
        Seconds since the epoch: ``time.time`` (the wall clock) by default, a
        :class:`VehicleClock` for a lockstep vehicle, any callable in tests.
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
