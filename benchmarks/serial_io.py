"""The serial link's hot path: reading a telemetry bundle off a tty and writing a command.

``run_serial(quick)`` returns a flat dict of figures (see :mod:`benchmarks.io_helpers`),
each the median over many periods, on a pseudo-terminal pair (the kernel's tty layer, as a
UART's, without the wire's speed):

- ``serial_us.read_bundle``: microseconds from "a period's telemetry (ATTITUDE_QUATERNION +
  LOCAL_POSITION_NED, 100 bytes) is waiting in the tty" to both messages decoded, with the
  daemon's way (``os.read`` on the raw non-blocking descriptor,
  :class:`mavreg.transport.framing.StreamFramer`, :class:`mavreg.transport.wire.Wire`); baseline:
  pyserial's ``Serial.read(in_waiting)`` feeding the same framer and codec;
- ``serial_us.read_bundle_pymavlink``: pymavlink's own serial connection
  (``mavutil.mavlink_connection(PATH, baud)``, ``recv_msg`` until both came) against the same
  daemon's way (the value), for "pyserial or pymavlink's serial support";
- ``serial_us.write_command``: one SET_ACTUATOR_CONTROL_TARGET frame and a TIMESYNC written
  (``os.write`` through :class:`mavreg.transport.tty.ByteStream` against ``Serial.write``);
- ``serial_us.p99.read_bundle``: the 99th percentile of the daemon's read, baseline pyserial's.

The bytes are put in the tty before the clock starts (the kernel's flip buffer is pushed
asynchronously), so the figures are the reader's own CPU time per period, not the line's.
Run alone: ``python -m benchmarks.serial_io [--quick]``.
"""
from __future__ import annotations

import fcntl
import os
import statistics
import struct
import termios
import time

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from benchmarks.io_helpers import figure
from benchmarks.report import standalone
from mavreg.transport.wire import Wire
from mavreg.transport.framing import StreamFramer
from mavreg.transport.tty import ByteStream, open_pty, open_serial

__all__ = ["run_serial"]

_VEHICLE = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)


def _bundle(k: int) -> bytes:
    return (mavlink2.MAVLink_attitude_quaternion_message(k, 0.99, 0.05, -0.1, 0.02, 0.01, -0.02, 0.03,
                                                         [0.0] * 4).pack(_VEHICLE)
            + mavlink2.MAVLink_local_position_ned_message(k, 1.5, -2.5, -6.0, 8.0, 0.5, -0.2).pack(_VEHICLE))


def _waiting(fd: int) -> int:
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]


def _timed_reads(master: int, reader_fd: int, consume, n: int) -> list[float]:
    """µs per period of ``consume()`` (which must take a whole bundle), the bundle waiting first."""
    out = []
    for k in range(n):
        data = _bundle(k)
        os.write(master, data)
        deadline = time.monotonic() + 1.0
        while _waiting(reader_fd) < len(data) and time.monotonic() < deadline:
            pass
        t0 = time.perf_counter_ns()
        consume()
        out.append((time.perf_counter_ns() - t0) / 1e3)
    return out


def _daemon_reader(fd: int):
    framer, wire = StreamFramer(), Wire(1, 191)

    def consume():
        got = 0
        while got < 2:
            try:
                data = os.read(fd, 65536)
            except BlockingIOError:
                continue
            frames = framer.feed(data)
            if frames:
                got += len(wire.parse(frames))
    return consume


def _pyserial_reader(port):
    framer, wire = StreamFramer(), Wire(1, 191)

    def consume():
        got = 0
        while got < 2:
            frames = framer.feed(port.read(port.in_waiting or 1))
            if frames:
                got += len(wire.parse(frames))
    return consume


def _pymavlink_reader(conn):
    def consume():
        got = 0
        deadline = time.monotonic() + 1.0
        while got < 2 and time.monotonic() < deadline:
            if conn.recv_msg() is not None:
                got += 1
        if got < 2:
            raise RuntimeError("pymavlink's serial connection did not decode the bundle")
    return consume


def _write_us(write, master: int, n: int) -> float:
    """Median µs of ``write(frames)`` of a command and a TIMESYNC, the line drained between writes."""
    cmd = mavlink2.MAVLink_set_actuator_control_target_message(1234567890123, 0, 1, 1, [0.31] * 4 + [0.0] * 4)
    ts = mavlink2.MAVLink_timesync_message(0, 1234567890123456)
    wire = Wire(1, 191)
    out = []
    for _ in range(n):
        t0 = time.perf_counter_ns()
        write(wire.pack(cmd) + wire.pack(ts))
        out.append((time.perf_counter_ns() - t0) / 1e3)
        _drain(master)
    return statistics.median(out)


def _drain(fd: int) -> None:
    try:
        while os.read(fd, 65536):
            pass
    except (BlockingIOError, OSError):
        pass


def run_serial(quick: bool) -> dict:
    """All the figures of the module docstring."""
    import serial
    os.environ["MAVLINK20"] = "1"           # pymavlink's connection then speaks MAVLink 2
    from pymavlink import mavutil
    n = 500 if quick else 3000
    master, slave, path = open_pty()
    fd = open_serial(path, 921600)
    port = serial.Serial(path, 921600, timeout=0)
    conn = mavutil.mavlink_connection(path, baud=921600, autoreconnect=False, dialect="common")
    try:
        ours = _timed_reads(master, fd, _daemon_reader(fd), n)
        theirs = _timed_reads(master, fd, _pyserial_reader(port), n)     # port and fd: the same tty
        mavutil_us = _timed_reads(master, fd, _pymavlink_reader(conn), n)
        stream = ByteStream(fd, path)
        write_ours = _write_us(stream.write, master, n)
        write_theirs = _write_us(port.write, master, n)
    finally:
        conn.close()
        port.close()
        os.close(fd)
        os.close(master)
        os.close(slave)
    p50, p50_base = statistics.median(ours), statistics.median(theirs)
    note = "os.read + StreamFramer + Wire.parse per period's telemetry (100 B)"
    return {
        "serial_us.read_bundle": figure(p50, p50_base, unit="us", higher_is_better=False,
                                        note=f"{note}; baseline pyserial Serial.read(in_waiting), same framer and codec"),
        "serial_us.p99.read_bundle": figure(float(np.percentile(ours, 99)), float(np.percentile(theirs, 99)),
                                            unit="us", higher_is_better=False, note="99th percentile of the above"),
        "serial_us.read_bundle_pymavlink": figure(p50, statistics.median(mavutil_us), unit="us",
                                                  higher_is_better=False,
                                                  note=f"{note}; baseline pymavlink mavserial recv_msg (its own parser)"),
        "serial_us.write_command": figure(write_ours, write_theirs, unit="us", higher_is_better=False,
                                          note="pack + write a command and a TIMESYNC: ByteStream.write (os.write) "
                                               "against pyserial Serial.write"),
    }


def main() -> None:
    standalone(run_serial, __doc__, quick_help="fewer periods")


if __name__ == "__main__":
    main()
