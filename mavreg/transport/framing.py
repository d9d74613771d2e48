"""Whole MAVLink frames out of a byte stream (sans-I/O: bytes in, frames out).

A serial line or a TCP connection delivers bytes, not datagrams: one read may end inside a
frame, and a line that loses or corrupts bytes leaves pieces of frames and noise between
whole ones. :class:`StreamFramer` keeps what is not complete yet for the next read, and
takes a frame only when its CRC (with the message's ``crc_extra``) holds; a start byte that
leads to no valid frame is skipped **one byte at a time**, so a corrupted frame costs that
frame and never the ones after it. A frame of a message id the dialect does not know
cannot be checked and is skipped as garbage (pymavlink's parser would refuse it too).

What it hands on is whole, valid frames, concatenated: the datagram parsers of the daemon
(:meth:`mavreg.transport.wire.Wire.parse`) and of the emulator take them as they take a datagram.
"""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

__all__ = ["StreamFramer", "FramerCounters", "MAX_FRAME_BYTES"]

try:                                    # what pymavlink itself uses when it is installed
    from fastcrc.crc16 import mcrf4xx as _crc
except ImportError:                     # pragma: no cover - pymavlink's own fallback then
    def _crc(data, crc: int = 0xFFFF) -> int:
        x = mavlink2.x25crc()
        x.crc = crc
        x.accumulate(bytes(data))
        return x.crc

_STX2 = 0xFD
_STX1 = 0xFE
_SIGNED = 0x01
_SIG_BYTES = 13
MAX_FRAME_BYTES = 10 + 255 + 2 + _SIG_BYTES
"""The longest MAVLink 2 frame (header, payload, CRC, signature)."""
_CRC_EXTRA = {mid: bytes([cls.crc_extra]) for mid, cls in mavlink2.mavlink_map.items()}


class FramerCounters:
    """What the framer saw, in bytes and frames (all since it was made)."""

    __slots__ = ("bytes_in", "frames", "garbage_bytes", "bad_frames")

    def __init__(self):
        self.bytes_in = 0
        self.frames = 0
        """Whole, valid frames handed on."""
        self.garbage_bytes = 0
        """Bytes skipped: noise between frames, pieces of broken frames."""
        self.bad_frames = 0
        """Start bytes that led to no valid frame (a CRC that failed, an unknown id or flag)."""


class StreamFramer:
    """Splits a byte stream into whole MAVLink 1 and 2 frames (see the module docstring)."""

    def __init__(self):
        self._buf = bytearray()
        self.counters = FramerCounters()

    @property
    def pending_bytes(self) -> int:
        """Bytes kept for the next :meth:`feed` (the start of a frame not complete yet)."""
        return len(self._buf)

    def feed(self, data: bytes) -> bytes:
        """The valid frames that ``data`` completes, concatenated; ``b""`` when none."""
        c = self.counters
        c.bytes_in += len(data)
        buf = self._buf
        buf += data
        n = len(buf)
        out = []
        i = 0
        while i < n:
            j = _next_start(buf, i)
            if j < 0:
                c.garbage_bytes += n - i
                i = n
                break
            c.garbage_bytes += j - i
            i = j
            size = _frame_size(buf, i, n)
            if size == 0:                    # the header is not complete yet
                break
            if size < 0:                     # a start byte with flags no frame has
                c.bad_frames += 1
                c.garbage_bytes += 1
                i += 1
                continue
            if n - i < size:                 # the rest of the frame comes with a later read
                break
            if _valid(buf, i, size):
                out.append(bytes(buf[i:i + size]))
                c.frames += 1
                i += size
            else:
                c.bad_frames += 1
                c.garbage_bytes += 1
                i += 1
        del buf[:i]
        return out[0] if len(out) == 1 else b"".join(out)


def _next_start(buf: bytearray, i: int) -> int:
    """Index of the next MAVLink 1 or 2 start byte at or after ``i``; -1 if none."""
    a = buf.find(_STX2, i)
    b = buf.find(_STX1, i)
    if a < 0:
        return b
    return a if b < 0 or a < b else b


def _frame_size(buf: bytearray, i: int, n: int) -> int:
    """The whole frame's length in bytes from its header at ``i``; 0 while the header is not
    all there; -1 when it cannot be a frame's header."""
    if buf[i] == _STX2:
        if n - i < 10:
            return 0
        flags = buf[i + 2]
        if flags & ~_SIGNED:
            return -1
        return 12 + buf[i + 1] + (_SIG_BYTES if flags & _SIGNED else 0)
    if n - i < 6:
        return 0
    return 8 + buf[i + 1]


def _valid(buf: bytearray, i: int, size: int) -> bool:
    """Whether the frame of ``size`` bytes at ``i`` has a known id and a CRC that holds."""
    if buf[i] == _STX2:
        mid = buf[i + 7] | (buf[i + 8] << 8) | (buf[i + 9] << 16)
        end = i + 10 + buf[i + 1]
    else:
        mid = buf[i + 5]
        end = i + 6 + buf[i + 1]
    extra = _CRC_EXTRA.get(mid)
    if extra is None:
        return False
    return _crc(extra, _crc(buf[i + 1:end])) == buf[end] | (buf[end + 1] << 8)
