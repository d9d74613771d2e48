"""MAVLink telemetry log in pymavlink's ``.tlog`` format.

Each record is an 8-byte big-endian unsigned timestamp (microseconds since the Unix
epoch) followed by the raw bytes of one MAVLink message, exactly as it went over the
wire. ``mavlogdump.py``, MAVProxy and ``mavutil.mavlink_connection(path)`` read it.
Messages in and out are both logged; the writer is buffered and flushed on close.
A SETUP_SIGNING frame (it carries a signing key) is never written, whichever way it went.

The timestamps come from an injected clock (:func:`tlog_clock`): for a vehicle in real time
:class:`SteadyWallClock`, the wall clock read once when the log opens and advanced by the
monotonic clock, so that a step of the host's clock mid-flight (NTP, an operator, ±1 h)
steps no stamp; :class:`VehicleClock` for a lockstep simulator, whose flight runs faster (or
slower) than the wall clock: there the log spans the flight's own (vehicle) time, so that
log tools (MAVExplorer, ``mavflightmodes.py``) show its real durations.

A write error (a full disk: ``ENOSPC``, ``EDQUOT``, ``EIO``) stops the log: the writer says
so once in one line (:func:`mavreg.daemon.logs.outputs.stopped_line`), keeps what it wrote, and
drops every later frame (counted in :attr:`TlogWriter.dropped`); the flight goes on. It never
raises into the link that calls it.
"""
from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import Callable

from ...progress import stderr_line
from .outputs import stopped_line

__all__ = ["TlogWriter", "VehicleClock", "SteadyWallClock", "tlog_clock"]

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


class SteadyWallClock:
    """Seconds since the epoch: the wall clock read once, advanced by a monotonic clock.

    A step of the wall clock after the start (±1 h) changes nothing: the stamps keep the
    spacing of real time and never go back.

    Parameters
    ----------
    wall_s, monotonic_s : callable, optional
        The wall clock (read once) and the monotonic clock (``time.time``, ``time.monotonic``).
    """

    def __init__(self, wall_s: Callable[[], float] = time.time,
                 monotonic_s: Callable[[], float] = time.monotonic):
        self._mono = monotonic_s
        self._offset_s = float(wall_s()) - float(monotonic_s())

    def __call__(self) -> float:
        return self._offset_s + self._mono()


def tlog_clock(kind: str, vehicle_time_s: Callable[[], float | None],
               wall_s: Callable[[], float] = time.time) -> Callable[[], float]:
    """The ``.tlog``'s clock: ``"vehicle"`` a :class:`VehicleClock` on ``vehicle_time_s``,
    ``"wall"`` a :class:`SteadyWallClock`; both start at ``wall_s()``."""
    if kind == "vehicle":
        return VehicleClock(vehicle_time_s, wall_s)
    return SteadyWallClock(wall_s)


class TlogWriter:
    """Append MAVLink message bytes with a timestamp.

    Parameters
    ----------
    path : path-like
        File to create (truncated if it exists).
    clock_s : callable, optional
        Seconds since the epoch: ``time.time`` (the wall clock) by default, a
        :class:`SteadyWallClock` or :class:`VehicleClock` in the daemon (:func:`tlog_clock`),
        any callable in tests.
    log : callable, optional
        Where the one line about a write error goes (stderr by default; the daemon's log).
    """

    def __init__(self, path: str | Path, clock_s: Callable[[], float] | None = None,
                 log: Callable[[str], None] | None = None):
        self.path = Path(path)
        self._clock = time.time if clock_s is None else clock_s
        self._log = stderr_line if log is None else log
        self.count = 0
        """Frames written (handed to the file's buffer)."""
        self.dropped = 0
        """Frames not written because the log stopped."""
        self.error: str | None = None
        """The line said when the log stopped (None while it writes)."""
        try:
            self._f = open(self.path, "wb", buffering=1 << 16)
        except OSError as exc:
            self._f = None
            self._stop(exc)

    def write(self, msgbuf: bytes) -> None:
        """Log one message's wire bytes (one MAVLink frame)."""
        if _carries_key(msgbuf):
            return
        self._put(_TS.pack(int(self._clock() * 1e6)) + bytes(msgbuf), 1)

    def write_many(self, frames) -> None:
        """Log frames that went over the wire together (one datagram): one time stamp, one write."""
        frames = [f for f in frames if not _carries_key(f)]
        if not frames:
            return
        ts = _TS.pack(int(self._clock() * 1e6))
        self._put(b"".join(ts + bytes(f) for f in frames), len(frames))

    def _put(self, data: bytes, n: int) -> None:
        if self._f is None or self._f.closed:
            self.dropped += n if self.error is not None else 0
            return
        try:
            self._f.write(data)
            self.count += n
        except OSError as exc:
            self.dropped += n
            self._stop(exc)

    def _stop(self, exc: OSError) -> None:
        """Stop for good after a write error: said once, the file closed as far as it can be."""
        self.error = stopped_line("tlog", self.path, exc, "the flight goes on")
        if self._f is not None:
            try:
                self._f.close()         # flushes what it can; the descriptor is closed either way
            except OSError:
                pass
        self._log(self.error)

    def status(self) -> dict:
        """``{"path", "frames", "dropped", "stopped"}`` for the daemon's status."""
        return {"path": str(self.path), "frames": self.count, "dropped": self.dropped, "stopped": self.error}

    def close(self) -> None:
        if self._f is not None and not self._f.closed:
            try:
                self._f.close()
            except OSError as exc:      # the last buffer did not fit: said like any other write
                self._stop(exc)

    def __enter__(self) -> "TlogWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
