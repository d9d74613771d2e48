"""A serial cable between two programs, for tests, that can be pulled out.

One end opens the emulator's port (``firmware-sim --listen pty`` announces it); the other is
a new pseudo-terminal whose slave the daemon opens (:attr:`PtyBridge.url`); a thread copies
the bytes both ways. :meth:`PtyBridge.pull` closes both ends at once, as a cable pulled out:
the daemon's reads then fail with EIO, and the emulator hears nothing more. (A line that
loses bytes is the emulator's own ``--serial-byte-loss``: seeded, and no extra hop.)
"""
from __future__ import annotations

import os
import select
import threading

from mavreg.transport.tty import open_pty, open_serial

__all__ = ["PtyBridge"]


class PtyBridge:
    def __init__(self, vehicle_port: str):
        self.vehicle_fd = open_serial(vehicle_port, 921600)
        self.master, self._slave, path = open_pty()
        self.url = f"serial:{path}:921600"
        self.bytes = {"down": 0, "up": 0}
        self.refused = {"down": 0, "up": 0}
        """Bytes an end did not take (nobody reading it yet)."""
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        ends = {self.vehicle_fd: (self.master, "down"), self.master: (self.vehicle_fd, "up")}
        while not self._stop.is_set():
            r, _, _ = select.select(list(ends), [], [], 0.05)
            for fd in r:
                try:
                    data = os.read(fd, 65536)
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    return
                to, way = ends[fd]
                self.bytes[way] += len(data)
                try:
                    os.write(to, data)
                except (BlockingIOError, InterruptedError):
                    self.refused[way] += len(data)       # a line that does not drain drops
                except OSError:
                    return

    def pull(self) -> None:
        """The cable pulled: nothing passes any more, and both ends are closed."""
        self._stop.set()
        self._thread.join(5)
        for fd in (self.vehicle_fd, self.master, self._slave):
            if fd >= 0:
                os.close(fd)
        self.vehicle_fd = self.master = self._slave = -1

    def close(self) -> None:
        if self.master >= 0:
            self.pull()
