"""MAVLink 2 frames of the hot messages, packed and parsed with precompiled structs: one codec for
the daemon and the emulator (bytes on the wire are the MAVLink specification's; the emulator's
independence is in its physics and control, not in its framing).

pymavlink's generated codec (``MAVLink.parse_buffer``, ``msg.pack``) costs about 10 µs a
message in pure Python: a byte-at-a-time state machine, a generic field loop, a header
object and a CRC object per frame. At 500 Hz with three telemetry messages and one or two
commands a period, that was the largest share of the daemon's own time. :class:`Wire` does
the same work for the messages the control loop handles every period with one
``struct`` call each and pymavlink's own fast CRC (``fastcrc``):

- :meth:`Wire.parse` splits a datagram into frames; a MAVLink 2 frame of a message in
  :data:`FAST_IDS` is checked (length, CRC with its ``crc_extra``) and decoded into the
  same pymavlink message class, with the same field values, header and wire bytes
  (signature included) as ``MAVLink.decode`` without a key gives; the signature of a
  signed frame is the link's to check (:mod:`mavreg.transport.signing`, :mod:`mavreg.transport.signing`). Anything else
  (MAVLink 1, other messages, garbage, a frame cut short) goes to pymavlink's own
  parser, exactly as the reference path does.
- :meth:`Wire.pack` packs any pymavlink message into a frame byte-identical to
  ``msg.pack(mav)`` (same sequence numbers, trailing-zero truncation, CRC); messages
  without a precompiled packer go through pymavlink.

``tests/unit/test_wire.py`` checks both directions against pymavlink on random values,
garbage and truncated input.
"""
from __future__ import annotations

import operator
import struct

from pymavlink.dialects.v20 import common as mavlink2

__all__ = ["Wire", "FAST_IDS", "crc_is_fast", "mcrf4xx"]

try:                                    # what pymavlink itself uses when it is installed
    from fastcrc.crc16 import mcrf4xx as _fast_mcrf4xx
except ImportError:                     # pragma: no cover - pymavlink then falls back too
    _fast_mcrf4xx = None


def _slow_mcrf4xx(data: bytes, crc: int = 0xFFFF) -> int:
    for b in data:
        tmp = b ^ (crc & 0xFF)
        tmp = (tmp ^ (tmp << 4)) & 0xFF
        crc = (crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4)
    return crc


mcrf4xx = _fast_mcrf4xx if _fast_mcrf4xx is not None else _slow_mcrf4xx
"""CRC-16/MCRF4XX (MAVLink's X.25 checksum) of ``data`` from ``crc``."""


def crc_is_fast() -> bool:
    """Whether pymavlink's compiled CRC (``fastcrc``) is in use, here and in pymavlink."""
    return _fast_mcrf4xx is not None and getattr(mavlink2, "x25crc", None) is getattr(
        mavlink2, "_x25crc_fast", object())


_STX = 0xFD
_HEADER = struct.Struct("<BBBBBBBHB")
_CRC = struct.Struct("<H")
_SIG_LEN = 13
_Header = mavlink2.MAVLink_header
_TEMPLATE_KEYS = ("_payload", "_msgbuf", "_crc", "_header")

FAST_CLASSES = (
    mavlink2.MAVLink_heartbeat_message,
    mavlink2.MAVLink_attitude_message,
    mavlink2.MAVLink_attitude_quaternion_message,
    mavlink2.MAVLink_local_position_ned_message,
    mavlink2.MAVLink_timesync_message,
    mavlink2.MAVLink_command_ack_message,
    mavlink2.MAVLink_set_actuator_control_target_message,
    mavlink2.MAVLink_command_long_message,
)
"""Messages with a precompiled decoder and packer (no strings among their fields)."""
FAST_IDS = frozenset(c.id for c in FAST_CLASSES)


class _Spec:
    """Precomputed layout of one message class."""

    def __init__(self, cls):
        self.cls = cls
        self.id = cls.id
        self.crc_extra = bytes([cls.crc_extra])
        self.unpacker = cls.unpacker
        self.size = cls.unpacker.size
        lengths = cls.lengths
        starts = [sum(lengths[:k]) for k in range(len(lengths))]
        # (name, start in the unpacked tuple, length) in declaration order (message fields)
        self.fields = tuple((name, starts[o], lengths[o], cls.array_lengths[o] > 0)
                            for name, o in zip(cls.fieldnames, cls.orders))
        self.plain = all(not arr for _, _, _, arr in self.fields)
        self.names = tuple(cls.ordered_fieldnames)      # the unpacked tuple's order (no arrays)
        # wire order for packing
        self.wire = tuple((name, lengths[k], cls.array_lengths[k] > 0)
                          for k, name in enumerate(cls.ordered_fieldnames))
        self.get_wire = operator.attrgetter(*[n for n, _, _ in self.wire])
        self.base = {"_fieldnames": cls.fieldnames, "_type": cls.msgname, "_signed": False,
                     "_link_id": None, "_instances": None,
                     "_instance_field": cls.instance_field, "_instance_offset": cls.instance_offset}

    def payload(self, msg) -> bytes:
        values = self.get_wire(msg)
        if len(self.wire) == 1:
            values = (values,)
        if self.plain:
            return self.unpacker.pack(*values)
        flat = []
        for (_, n, arr), v in zip(self.wire, values):
            if arr:
                flat.extend(v[:n])
            else:
                flat.append(v)
        return self.unpacker.pack(*flat)

    def message(self, t: tuple, frame: bytearray, header, plen: int, crc: int, sig: int = 0):
        d = dict(self.base)
        if self.plain:
            d.update(zip(self.names, t))
        else:
            for name, start, n, arr in self.fields:
                d[name] = list(t[start:start + n]) if arr else t[start]
        d["_header"] = header
        d["_msgbuf"] = frame
        d["_payload"] = frame[6:-2 - sig]
        d["_crc"] = crc
        m = object.__new__(self.cls)
        m.__dict__ = d
        return m


_SPECS = {c.id: _Spec(c) for c in FAST_CLASSES}


class Wire:
    """One end of a MAVLink 2 link: our identity, our sequence numbers, the parser.

    Parameters
    ----------
    system_id, component_id : int
        The identity packed into every frame sent.
    """

    def __init__(self, system_id: int, component_id: int):
        self.system_id = int(system_id)
        self.component_id = int(component_id)
        self.mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.seq = 0
        self.fast_in = 0
        """Frames decoded by the precompiled decoders."""
        self.slow_in = 0
        """Datagrams (or their tails) handed to pymavlink's parser."""

    def identify(self, system_id: int) -> None:
        """Pack every later frame as ``system_id`` (the vehicle's, once it is known)."""
        self.system_id = int(system_id)
        self.mav.srcSystem = self.system_id

    # ------------------------------------------------------------------ sending
    def pack(self, msg) -> bytes:
        """The frame of ``msg`` with the next sequence number (as ``msg.pack(mav)`` and
        ``MAVLink.send`` would give it)."""
        spec = _SPECS.get(type(msg).id)
        seq = self.seq
        self.seq = (seq + 1) & 0xFF
        if spec is None:
            self.mav.seq = seq
            return msg.pack(self.mav)
        payload = spec.payload(msg)
        trimmed = payload.rstrip(b"\x00") or payload[:1]
        mid = spec.id
        body = _HEADER.pack(_STX, len(trimmed), 0, 0, seq, self.system_id, self.component_id,
                            mid & 0xFFFF, mid >> 16) + trimmed
        crc = mcrf4xx(spec.crc_extra, mcrf4xx(body[1:]))
        return body + _CRC.pack(crc)

    # ------------------------------------------------------------------ receiving
    def parse(self, data: bytes, skip: frozenset | set = frozenset()) -> list:
        """Decoded messages of one datagram, in order (``BAD_DATA`` for what is not a frame).

        A whole, valid frame of a message id in ``skip`` is not decoded: its wire bytes
        (``bytes``) stand in its place in the list.
        """
        mav = self.mav
        if len(mav.buf) > mav.buf_index:  # a frame cut short earlier: the reference parser owns it
            self.slow_in += 1
            return mav.parse_buffer(data) or []
        out = []
        n = len(data)
        i = 0
        specs = _SPECS
        view = memoryview(data)
        while i < n:
            flags = data[i + 2] if n - i >= 12 else 0xFF
            if data[i] != _STX or flags & 0xFE:
                break                    # MAVLink 1, unknown flags, garbage or a short tail
            plen = data[i + 1]
            sig = _SIG_LEN if flags else 0   # a signed frame: decoded here, verified by the link
            end = i + 12 + plen + sig
            spec = specs.get(data[i + 7] | (data[i + 8] << 8) | (data[i + 9] << 16))
            if spec is None or end > n or plen > spec.size:
                break
            cend = end - sig
            crc = data[cend - 2] | (data[cend - 1] << 8)
            if mcrf4xx(spec.crc_extra, mcrf4xx(view[i + 1:cend - 2])) != crc:
                break                    # pymavlink reports it (BAD_DATA) as the reference does
            if spec.id in skip:
                out.append(bytes(view[i:end]))
                i = end
                continue
            if plen == spec.size:
                t = spec.unpacker.unpack_from(data, i + 10)
            else:                        # MAVLink 2 dropped the payload's trailing zeros
                t = spec.unpacker.unpack(bytes(view[i + 10:cend - 2]) + bytes(spec.size - plen))
            frame = bytearray(view[i:end])
            header = _Header(spec.id, flags, data[i + 3], plen, data[i + 4], data[i + 5], data[i + 6])
            out.append(spec.message(t, frame, header, plen, crc, sig))
            i = end
        self.fast_in += len(out)
        if i < n:
            self.slow_in += 1
            out.extend(mav.parse_buffer(data[i:]) or [])
        return out
