"""A serial device, a new pseudo-terminal or a TCP socket as one non-blocking byte stream.

A tty is put in raw mode with termios (no echo, no line editing, no CR/LF translation,
8 data bits, no parity, receiver on, modem lines ignored) at the baud asked for, and read
with ``os.read`` on its non-blocking descriptor: the asyncio daemon watches it with
``loop.add_reader``, as its UDP socket. pyserial does the same termios calls but adds a
``select`` and Python layers to every read (``benchmarks/serial_io.py`` measures both;
docs/serial.md has the figures), so it is not used.

Errors a user can cause (a missing device, no permission, a speed the platform cannot set,
nobody listening on a TCP port) are ``OSError`` with a one-line message that names the
device or the address.
"""
from __future__ import annotations

import errno
import os
import socket
import termios
import tty

__all__ = ["ByteStream", "open_serial", "open_pty", "set_raw", "supported_baud", "tcp_socket",
           "STANDARD_BAUDS"]

STANDARD_BAUDS = tuple(sorted(int(name[1:]) for name in dir(termios)
                              if name[:1] == "B" and name[1:].isdigit() and int(name[1:]) > 0))
"""The bauds termios can set on this platform (Linux: 50 ... 4000000)."""
_READ_BYTES = 65536


def supported_baud(baud_bps: int) -> bool:
    return baud_bps in STANDARD_BAUDS


def set_raw(fd: int, baud_bps: int | None = None) -> None:
    """Raw mode (8N1, no echo, no translation, receiver on, modem lines ignored) and, if given,
    the line speed."""
    tty.setraw(fd, termios.TCSANOW)
    attrs = termios.tcgetattr(fd)
    attrs[2] |= termios.CLOCAL | termios.CREAD
    attrs[2] &= ~(termios.CSTOPB | termios.PARENB | termios.CRTSCTS)
    if baud_bps is not None:
        speed = getattr(termios, f"B{baud_bps}", None)
        if speed is None:
            raise OSError(errno.EINVAL, f"baud {baud_bps} cannot be set here; one of "
                          f"{', '.join(str(b) for b in STANDARD_BAUDS if b >= 9600)}")
        attrs[4] = attrs[5] = speed
    termios.tcsetattr(fd, termios.TCSANOW, attrs)


def open_serial(path: str, baud_bps: int) -> int:
    """The device at ``path`` opened non-blocking, raw, at ``baud_bps``, with whatever it had
    received before dropped (stale telemetry); OSError naming it."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError as exc:
        hint = (": add the user to the device's group (e.g. dialout)" if exc.errno == errno.EACCES else "")
        raise OSError(exc.errno, f"serial port {path}: {exc.strerror}{hint}") from None
    try:
        if not os.isatty(fd):
            raise OSError(errno.ENOTTY, "not a terminal device")
        set_raw(fd, baud_bps)
        termios.tcflush(fd, termios.TCIOFLUSH)
    except (OSError, termios.error) as exc:
        os.close(fd)
        code, text = (exc.args[0], exc.args[-1]) if isinstance(exc, termios.error) else (exc.errno, exc.strerror)
        raise OSError(code, f"serial port {path}: {text}") from None
    return fd


def open_pty() -> tuple[int, int, str]:
    """A new pseudo-terminal pair, both ends raw: ``(master fd, slave fd, slave path)``.

    The master is non-blocking. Keep the slave descriptor open while the master is used: with
    no slave open, reading the master fails with EIO at once and ``select`` reports it
    readable forever."""
    master, slave = os.openpty()
    set_raw(slave)
    set_raw(master)
    os.set_blocking(master, False)
    return master, slave, os.ttyname(slave)


def tcp_socket(host: str, port: int) -> tuple[socket.socket, tuple]:
    """A non-blocking TCP socket for ``host:port`` (Nagle off: a command leaves at once) and
    the address to connect to or bind; OSError naming the address."""
    try:
        info = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as exc:
        raise OSError(errno.EINVAL, f"tcp {host}:{port}: {exc.strerror}") from None
    sock = socket.socket(info[0], socket.SOCK_STREAM)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.setblocking(False)
    return sock, info[4]


class ByteStream:
    """One non-blocking descriptor (a tty or a connected socket), read and written with
    ``os.read``/``os.write``.

    Parameters
    ----------
    fd : int
    name : str
        What to call it in messages (the URL).
    owner : object, optional
        Closed instead of ``fd`` (a socket object), with anything in ``keep`` (a pty's slave).
    """

    def __init__(self, fd: int, name: str, owner=None, keep=()):
        self.fd = fd
        self.name = name
        self._owner = owner
        self._keep = tuple(keep)
        self._pending = b""
        self.closed_reason: str | None = None
        """Why the stream ended (the other end closed, the device vanished); None while open."""
        self.dropped_bytes = 0
        """Bytes not written: the line took none of them (:meth:`write`)."""

    def fileno(self) -> int:
        return self.fd

    def read(self) -> bytes | None:
        """What is waiting (``b""`` when nothing is); None once the stream has ended."""
        if self.closed_reason is not None:
            return None
        try:
            data = os.read(self.fd, _READ_BYTES)
        except (BlockingIOError, InterruptedError):
            return b""
        except OSError as exc:          # EIO: the other end of a pty closed, a USB device unplugged
            self.closed_reason = f"{self.name}: {exc.strerror or exc}"
            return None
        if not data:
            self.closed_reason = f"{self.name}: closed by the other end"
            return None
        return data

    def write(self, data: bytes) -> bool:
        """Write ``data``; False if it was dropped (counted in :attr:`dropped_bytes`).

        A line that takes part of a write keeps the rest, to finish that frame before the
        next write; a line that takes nothing (nobody reads, it is congested) drops the
        write whole, as a UART whose transmit buffer is full: stale telemetry never queues
        up to reach a reader late."""
        if self.closed_reason is not None:
            self.dropped_bytes += len(data)
            return False
        if self._pending:
            self._send(self._pending)
            if self._pending:              # the line still owes the last frame's end
                self.dropped_bytes += len(data)
                return False
        if self._send(data) == 0:
            self._pending = b""
            self.dropped_bytes += len(data)
            return False
        return True

    def _send(self, data: bytes) -> int:
        """Write what the line takes of ``data`` and keep the rest; the bytes written."""
        try:
            n = os.write(self.fd, data)
        except (BlockingIOError, InterruptedError):
            n = 0
        except OSError as exc:
            self.closed_reason = f"{self.name}: {exc.strerror or exc}"
            n = 0
        self._pending = data[n:]
        return n

    def close(self) -> None:
        if self.fd < 0:
            return
        for fd in self._keep:
            os.close(fd)
        if self._owner is not None:
            self._owner.close()
        else:
            os.close(self.fd)
        self.fd = -1
