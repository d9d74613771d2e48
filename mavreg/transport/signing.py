"""MAVLink 2 message signing for the daemon: the key file, a sans-I/O verifier, the signer.

The daemon signs every frame it sends and, with signing on, accepts a frame from the link
only if :class:`Verifier` says so. The rules (MAVLink's message-signing specification, with
the order of two steps fixed, see below):

- **Key**: 32 bytes in a file of its own, written as 64 hexadecimal characters or as base64
  (surrounding white space ignored). :func:`load_key` refuses a file that group or others
  may read or write, anything that is not exactly 32 bytes, and the all-zero key (PX4 reads
  it as "signing off"). Its one-line errors name the file, never its content.
- **Unsigned** frames (MAVLink 1 frames are unsigned by construction) are dropped, except
  RADIO_STATUS: the specification's example of what a system should accept unsigned
  (radios inject it and cannot sign). SETUP_SIGNING is never accepted over the link.
- **Signature**: the first 6 bytes of SHA-256(key + frame up to and including the
  timestamp), compared in constant time.
- **Replay**: a *stream* is (link id, system id, component id). A timestamp at or below the
  last one accepted on its stream is a replay; a stream not seen before is refused if its
  timestamp is more than one minute older than the newest timestamp we know. The table
  keeps at most :data:`MAX_STREAMS` streams (least recently used evicted); a new stream must
  also be newer than any evicted one, so eviction reopens nothing.
- The signature is checked **before** the stream table is touched. pymavlink 2.4's
  ``MAVLink.check_signature`` stores a new stream's timestamp first, so one forged frame
  with a future timestamp (signature wrong) blocks the genuine stream for good; this
  module never calls it.

Timestamps count 10 µs since 2015-01-01 00:00 UTC. :class:`Signing` (the only part with I/O)
keeps the newest one (sent or accepted) and the stream table in a state file and starts
from the larger of the saved value and the clock, so a restart can be neither replayed into
nor made to reuse a timestamp.
"""
from __future__ import annotations

import base64
import binascii
import errno
import hashlib
import hmac
import json
import os
import stat
import sys
import time
from collections import OrderedDict
from pathlib import Path
from typing import Callable

from pymavlink.dialects.v20 import common as mavlink2

from .wire import mcrf4xx

__all__ = ["SigningError", "load_key", "now_ticks", "Verifier", "Signer", "Signing", "REASONS", "MAX_STREAMS",
           "ALLOWED_UNSIGNED", "SETUP_SIGNING_ID", "TICKS_PER_S", "state_path"]

TICKS_PER_S = 100_000
"""Signing timestamps count 10 µs."""
EPOCH_2015_S = 1_420_070_400
MINUTE_TICKS = 60 * TICKS_PER_S
MAX_STREAMS = 64
ALLOWED_UNSIGNED = frozenset({mavlink2.MAVLINK_MSG_ID_RADIO_STATUS})
SETUP_SIGNING_ID = mavlink2.MAVLINK_MSG_ID_SETUP_SIGNING
REASONS = ("unsigned", "bad_signature", "replayed")
"""Why the verifier drops a frame (the link counts each)."""
SAVE_EVERY_S = 10.0
"""The state file is rewritten at least this often while frames are signed (the
specification asks for at least once a minute), and at close."""
_IFLAG_SIGNED = 0x01
_CRC_EXTRA = {mid: bytes([cls.crc_extra]) for mid, cls in mavlink2.mavlink_map.items()}
_SIG_LEN = 13
_MAX_KEY_FILE_BYTES = 4096


class SigningError(ValueError):
    """A key or state file that cannot be used: one line naming the file (mavreg's commands exit 2
    on it, :data:`mavreg.errors.REGISTERED`; the emulator's too)."""


def load_key(path) -> bytes:
    """The 32-byte key in ``path`` (64 hex characters or base64).

    Raises
    ------
    ValueError
        One line naming the file and the fault (mode, size, format), never the content.
    """
    p = Path(path)
    try:
        st = p.stat()
        if not stat.S_ISREG(st.st_mode):
            raise SigningError(f"signing key {p}: not a regular file")
        if st.st_mode & 0o077:
            raise SigningError(f"signing key {p}: group or others may read or write it (mode "
                             f"{stat.S_IMODE(st.st_mode):04o}); chmod 600 {p}")
        with open(p, "rb") as f:
            raw = f.read(_MAX_KEY_FILE_BYTES + 1)
    except OSError as exc:
        raise SigningError(f"signing key {p}: {exc.strerror or exc}") from None
    text = raw.strip() if len(raw) <= _MAX_KEY_FILE_BYTES else b""
    key = None
    if len(text) == 64:
        try:
            key = bytes.fromhex(text.decode("ascii"))
        except (UnicodeDecodeError, ValueError):
            key = None
    if key is None and text:
        try:
            key = base64.b64decode(text, validate=True)
        except (binascii.Error, ValueError):
            key = None
    if key is None or len(key) != 32:
        raise SigningError(f"signing key {p}: expected 32 bytes as 64 hex characters or base64")
    if not any(key):
        raise SigningError(f"signing key {p}: the all-zero key is not a key")
    return key


def now_ticks(wall_s: Callable[[], float] = time.time) -> int:
    """The signing clock: 10 µs units since 2015-01-01 00:00 UTC."""
    return max(0, int((wall_s() - EPOCH_2015_S) * TICKS_PER_S))


def _msgid(frame) -> int:
    if frame[0] == 0xFE:
        return frame[5]
    return frame[7] | (frame[8] << 8) | (frame[9] << 16)


class Verifier:
    """Checks signed frames against the key and the per-stream timestamps (no I/O, no clock).

    Parameters
    ----------
    key : bytes
        32 bytes.
    newest_ticks : int
        The newest timestamp known at start (the larger of the clock and the saved state).
    streams : dict, optional
        ``{(link_id, system_id, component_id): last timestamp}`` restored from the state.
    max_streams : int
    """

    def __init__(self, key: bytes, newest_ticks: int = 0, streams: dict | None = None,
                 max_streams: int = MAX_STREAMS):
        self._keyed = hashlib.sha256(bytes(key))     # SHA-256 state after the key, copied per frame
        self.newest_ticks = int(newest_ticks)
        self.max_streams = int(max_streams)
        self.streams: OrderedDict = OrderedDict(sorted((streams or {}).items(), key=lambda kv: kv[1]))
        self.evicted_ticks = 0
        """The newest timestamp of a stream evicted from the table: new streams must pass it."""
        while len(self.streams) > self.max_streams:
            self._evict()

    def check(self, frame) -> str | None:
        """``None`` if ``frame`` (one whole MAVLink frame) is accepted, else the reason.

        An accepted signed frame advances its stream and :attr:`newest_ticks`; nothing else
        changes any state.
        """
        n = len(frame)
        if n < 8 or frame[0] not in (0xFD, 0xFE) or (frame[0] == 0xFD and n < 12):
            return "unsigned"
        if frame[0] == 0xFE or not frame[2] & _IFLAG_SIGNED:
            return None if _msgid(frame) in ALLOWED_UNSIGNED else "unsigned"
        if n != 12 + frame[1] + _SIG_LEN:
            return "bad_signature"
        frame = bytes(frame)
        h = self._keyed.copy()
        h.update(memoryview(frame)[:-6])
        if not hmac.compare_digest(h.digest()[:6], frame[-6:]):
            return "bad_signature"
        ts = int.from_bytes(frame[-12:-6], "little")
        stream = (frame[-13], frame[5], frame[6])
        last = self.streams.get(stream)
        if last is not None:
            if ts <= last:
                return "replayed"
            self.streams.move_to_end(stream)
        elif ts + MINUTE_TICKS < self.newest_ticks or ts <= self.evicted_ticks:
            return "replayed"
        self.streams[stream] = ts
        if len(self.streams) > self.max_streams:
            self._evict()
        if ts > self.newest_ticks:
            self.newest_ticks = ts
        return None

    def _evict(self) -> None:
        _, ts = self.streams.popitem(last=False)
        self.evicted_ticks = max(self.evicted_ticks, ts)


class Signer:
    """Turns unsigned MAVLink 2 frames into signed ones (no I/O; the clock is injected).

    Parameters
    ----------
    key : bytes
    clock_ticks : callable
        The signing clock (:func:`now_ticks`).
    start_ticks : int
        No timestamp at or below this one is used.
    link_id : int
    """

    def __init__(self, key: bytes, clock_ticks: Callable[[], int], start_ticks: int = 0, link_id: int = 0):
        self._keyed = hashlib.sha256(bytes(key))
        self._clock = clock_ticks
        self.timestamp = int(start_ticks)
        self._link = bytes([link_id & 0xFF])

    def sign(self, frame) -> bytes:
        """The signed form of the unsigned MAVLink 2 ``frame`` (MAVLink 1 is returned as is)."""
        if frame[0] != 0xFD or frame[2] & _IFLAG_SIGNED:
            return bytes(frame)
        body = bytearray(frame[:-2])
        body[2] |= _IFLAG_SIGNED
        crc_extra = _CRC_EXTRA[_msgid(frame)]
        body += mcrf4xx(crc_extra, mcrf4xx(memoryview(body)[1:])).to_bytes(2, "little")
        ts = max(self.timestamp + 1, self._clock())
        self.timestamp = ts
        body += self._link + ts.to_bytes(6, "little")
        h = self._keyed.copy()
        h.update(body)
        return bytes(body + h.digest()[:6])


def _stderr_line(text: str) -> None:
    sys.stderr.write(text + "\n")
    sys.stderr.flush()


def state_path(key_path, role: str) -> Path:
    """Where :class:`Signing` keeps its state: beside the key, ``KEY.ROLE-state.json``."""
    p = Path(key_path)
    return p.with_name(f"{p.name}.{role}-state.json")


class Signing:
    """One side's signing: key, verifier, signer, and the state file that outlives a restart.

    Parameters
    ----------
    key_path : path-like
    role : str
        Names the state file (:func:`state_path`); each process holding the key has its own.
    wall_s : callable
        Wall clock (seconds since the epoch), injected for tests. A step back of it (an NTP
        correction, an operator) never makes a timestamp go back: :class:`Signer` sends the
        larger of the clock and its last timestamp plus one, as the specification asks
        (pymavlink reads the clock once and adds one per frame; the C library likewise).
    log : callable, optional
        Where the one line about a state file that could not be rewritten during the flight
        goes (stderr by default). The flight goes on: the state is kept in memory and the
        next save tries again.

    Raises
    ------
    ValueError
        Bad key file, or a state file that cannot be read or written (one line).
    """

    def __init__(self, key_path, role: str, wall_s: Callable[[], float] = time.time,
                 log: Callable[[str], None] | None = None):
        key = load_key(key_path)
        self._log = log
        self.path = state_path(key_path, role)
        self._wall = wall_s
        saved, streams = self._load()
        start = max(saved, now_ticks(wall_s))
        self.verifier = Verifier(key, start, streams)
        self.signer = Signer(key, lambda: now_ticks(self._wall), start)
        self.drops = dict.fromkeys(REASONS, 0)
        self.accepted = 0
        self.save_errors = 0
        self._saved = False
        self._next_save_s = 0.0
        self.save()                       # writable now, or a one-line error before the flight

    def _load(self) -> tuple[int, dict]:
        try:
            text = self.path.read_text()
        except FileNotFoundError:
            return 0, {}
        except OSError as exc:
            raise SigningError(f"signing state {self.path}: {exc.strerror or exc}") from None
        try:
            d = json.loads(text)
            streams = {(int(a), int(b), int(c)): int(t) for a, b, c, t in d.get("streams", [])}
            return int(d["timestamp"]), streams
        except (ValueError, KeyError, TypeError, AttributeError):
            raise SigningError(f"signing state {self.path}: unreadable; it guards against replays, "
                             "remove it only if you know why it is broken") from None

    def check(self, frame) -> str | None:
        """The verifier's verdict on one received frame; a drop is counted."""
        reason = self.verifier.check(frame)
        if reason is None:
            self.accepted += 1
            if self.verifier.newest_ticks > self.signer.timestamp:
                self.signer.timestamp = self.verifier.newest_ticks
        else:
            self.drops[reason] += 1
        return reason

    def sign(self, frame) -> bytes:
        """Sign one outgoing frame; the state is saved every :data:`SAVE_EVERY_S`."""
        out = self.signer.sign(frame)
        now = time.monotonic()
        if now >= self._next_save_s:
            self.save()
        return out

    def save(self) -> None:
        """Write the newest timestamp and the stream table (atomically, mode 0600).

        Raises ValueError on a write error only before the first save succeeded; later
        errors are counted (:attr:`save_errors`), the first one is said in one line, and the
        flight goes on.
        """
        newest = max(self.signer.timestamp, self.verifier.newest_ticks)
        data = {"timestamp": newest,
                "streams": [[*k, t] for k, t in self.verifier.streams.items()]}
        tmp = self.path.with_name(self.path.name + ".tmp")
        self._next_save_s = time.monotonic() + SAVE_EVERY_S
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
            with os.fdopen(fd, "w") as f:
                json.dump(data, f)
            os.replace(tmp, self.path)
            self._saved = True
        except OSError as exc:
            self.save_errors += 1
            try:
                os.unlink(tmp)          # a partial temporary file would only hold the space
            except OSError:
                pass
            if not self._saved:
                raise SigningError(f"signing state {self.path}: cannot write: {exc.strerror or exc}") from None
            if self.save_errors == 1:
                code = f"[Errno {exc.errno} {errno.errorcode.get(exc.errno, '?')}] " if exc.errno else ""
                line = (f"signing: cannot write {self.path}: {code}{exc.strerror or exc}; the flight goes on "
                        f"(the state is kept in memory, saving is tried again every {SAVE_EVERY_S:g} s)")
                (self._log or _stderr_line)(line)
