"""MAVLink codec cost per message: the precompiled codec against pymavlink, and pymavlink's CRC.

``run_codec(quick)`` returns a flat dict of figures (see :mod:`benchmarks.io_helpers`):

- ``codec_us.pack.<MESSAGE>`` / ``codec_us.parse.<MESSAGE>`` for the hot messages
  (ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED, SET_ACTUATOR_CONTROL_TARGET,
  TIMESYNC, HEARTBEAT): microseconds per message with :class:`mavreg.transport.wire.Wire`
  (value) and with pymavlink's generated codec, ``msg.pack(mav)`` and
  ``MAVLink.parse_buffer`` with robust parsing (baseline); median of 5 runs;
- ``pymavlink_fast_crc``: 1 when pymavlink computes its CRC with the compiled ``fastcrc``
  (pymavlink 2.4.4x: ``x25crc`` is ``_x25crc_fast``), 0 when it fell back to pure Python
  (a warning is issued then: ``pip install fastcrc``);
- ``crc_us.frame``: CRC-16/MCRF4XX of a 40-byte frame with ``fastcrc`` against pymavlink's
  pure-Python fallback.

Run alone: ``python -m benchmarks.codec [--quick]``.
"""
from __future__ import annotations

import statistics
import time
import warnings
from pymavlink.dialects.v20 import common as mavlink2

from benchmarks.report import standalone
from benchmarks.io_helpers import figure
from mavreg.transport import wire as wire_mod

__all__ = ["run_codec", "hot_messages", "pymavlink_crc_is_fast"]


def hot_messages() -> list:
    """One message of each hot type, with realistic values."""
    return [
        mavlink2.MAVLink_attitude_message(123456, 0.1, -0.2, 1.3, 0.01, -0.02, 0.03),
        mavlink2.MAVLink_attitude_quaternion_message(123456, 0.99, 0.05, -0.1, 0.02, 0.01, -0.02, 0.03,
                                                     [0.0, 0.0, 0.0, 0.0]),
        mavlink2.MAVLink_local_position_ned_message(123456, 1.5, -2.5, -6.0, 8.0, 0.5, -0.2),
        mavlink2.MAVLink_set_actuator_control_target_message(1234567890123, 0, 1, 1,
                                                             [0.31, 0.29, 0.33, 0.30, 0.0, 0.0, 0.0, 0.0]),
        mavlink2.MAVLink_timesync_message(0, 1234567890123456),
        mavlink2.MAVLink_heartbeat_message(2, 12, 129, 393216, 4, 3),
    ]


def pymavlink_crc_is_fast() -> bool:
    """Whether pymavlink's generated dialect uses the compiled CRC."""
    return getattr(mavlink2, "x25crc", None) is getattr(mavlink2, "_x25crc_fast", object())


def _per_call_us(fn, n: int) -> float:
    runs = []
    for _ in range(5):
        t0 = time.perf_counter()
        for _ in range(n):
            fn()
        runs.append((time.perf_counter() - t0) / n * 1e6)
    return statistics.median(runs)


def run_codec(quick: bool) -> dict:
    """All the figures of the module docstring."""
    n = 2000 if quick else 5000
    fig = {}
    for msg in hot_messages():
        name = msg.get_type()
        mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
        wire = wire_mod.Wire(1, 1)
        frame = msg.pack(mav)
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        reader = wire_mod.Wire(1, 191)
        fig[f"codec_us.pack.{name}"] = figure(
            _per_call_us(lambda: wire.pack(msg), n), _per_call_us(lambda: msg.pack(mav), n), unit="us",
            higher_is_better=False, note="mavreg.transport.wire.Wire.pack against pymavlink msg.pack(mav)")
        fig[f"codec_us.parse.{name}"] = figure(
            _per_call_us(lambda: reader.parse(frame), n), _per_call_us(lambda: parser.parse_buffer(frame), n),
            unit="us", higher_is_better=False,
            note="Wire.parse against pymavlink MAVLink.parse_buffer (robust parsing), one frame per datagram")
    fast = pymavlink_crc_is_fast()
    if not fast:
        warnings.warn("pymavlink computes its CRC in pure Python (fastcrc is not installed): "
                      "pip install fastcrc", RuntimeWarning, stacklevel=2)
    fig["pymavlink_fast_crc"] = figure(
        1.0 if fast else 0.0, None, unit="bool", higher_is_better=True,
        note="pymavlink's x25crc is the compiled fastcrc path" if fast else
        "WARNING: pymavlink's CRC is pure Python (fastcrc missing); every pack and parse pays for it")
    frame40 = bytes(range(40))
    if wire_mod._fast_mcrf4xx is not None:
        fast_us = _per_call_us(lambda: wire_mod._fast_mcrf4xx(frame40, 0xFFFF), n)
    else:
        fast_us = None
    fig["crc_us.frame"] = figure(fast_us, _per_call_us(lambda: wire_mod._slow_mcrf4xx(frame40), n // 4 or 1),
                                 unit="us", higher_is_better=False,
                                 note="CRC-16/MCRF4XX of 40 bytes: fastcrc against the pure-Python fallback")
    return fig


def main() -> None:
    standalone(run_codec, __doc__, quick_help="fewer calls per timing")


if __name__ == "__main__":
    main()
