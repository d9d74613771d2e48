"""Bytes on the wire: the MAVLink 2 codec and signing, and the byte-stream links to a vehicle (a
serial port: a UART, a USB CDC device, a pseudo-terminal; or a TCP connection) beside the
daemon's UDP sockets.

- :mod:`.urls`: ``serial:PATH[:BAUD]``, ``tcp:HOST:PORT``, ``tcpin:HOST:PORT`` parsed, one
  line on anything else;
- :mod:`.wire`: the MAVLink 2 codec of the hot messages (precompiled structs, pymavlink's
  fast CRC; byte-identical to pymavlink), the daemon's and the emulator's;
- :mod:`.framing`: the sans-I/O frame splitter: bytes in, whole CRC-checked MAVLink frames
  out, garbage and broken frames skipped and counted;
- :mod:`.signing`: MAVLink 2 signing (key file, sans-I/O verifier, signer), both sides';
- :mod:`.tty`: a serial device or a new pseudo-terminal in raw mode (termios), a TCP
  socket, as one non-blocking :class:`~.tty.ByteStream`.

(What a stream set-up needs of a UART's baud is the daemon's: :mod:`mavreg.daemon.vehicle.link_budget`.)
Shared by the daemon (``mavreg fly``/``serve --vehicle serial:...``) and the emulator
(``firmware-sim --listen pty``): a transport, not vehicle behaviour (docs/architecture.md).
"""
