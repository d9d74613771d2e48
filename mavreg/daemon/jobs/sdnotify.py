"""systemd's readiness protocol (``sd_notify``), for ``mavreg serve`` as a ``Type=notify`` unit.

The protocol is one datagram of ``KEY=VALUE`` lines to the Unix socket named in
``$NOTIFY_SOCKET`` (a path, or an abstract socket when it starts with ``@``): ``READY=1``
once the service works, ``STATUS=...`` a line that ``systemctl status`` shows,
``WATCHDOG=1`` a keep-alive when the unit sets ``WatchdogSec=`` (systemd then gives the
interval in ``$WATCHDOG_USEC``, and ``$WATCHDOG_PID`` the process it expects it from).
Outside systemd (no ``$NOTIFY_SOCKET``) every call does nothing. It is a dozen lines, so it is
written here rather than taken from a package (python-systemd needs libsystemd's headers
to build; the pure-Python ones add a dependency for one ``sendto``).

A notification never fails the daemon: a socket that is gone or refuses is ignored (the
daemon flies whether or not systemd hears it).
"""
from __future__ import annotations

import os
import socket

__all__ = ["Notifier"]


class Notifier:
    """Notifications to ``$NOTIFY_SOCKET`` (``environ``: the process environment by default).

    ``enabled``: a socket was named. ``watchdog_s``: how often to send ``WATCHDOG=1`` (half
    the unit's ``WatchdogSec``, as systemd advises), or None when no watchdog is asked of this
    process.
    """

    def __init__(self, environ: dict | None = None):
        env = os.environ if environ is None else environ
        path = env.get("NOTIFY_SOCKET", "")
        self.address = "\0" + path[1:] if path.startswith("@") else path
        self.enabled = bool(path)
        self.watchdog_s = _watchdog_period_s(env)

    def send(self, *lines: str) -> bool:
        """Send ``lines`` as one datagram; True when it was sent."""
        if not self.enabled:
            return False
        data = "\n".join(line.replace("\n", " ") for line in lines).encode("utf-8", "replace")
        try:
            with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
                sock.sendto(data, self.address)
        except OSError:
            return False
        return True

    def ready(self, status: str) -> bool:
        return self.send("READY=1", f"STATUS={status}")

    def status(self, status: str) -> bool:
        return self.send(f"STATUS={status}")

    def watchdog(self) -> bool:
        return self.watchdog_s is not None and self.send("WATCHDOG=1")

    def stopping(self, status: str) -> bool:
        return self.send("STOPPING=1", f"STATUS={status}")


def _watchdog_period_s(env) -> float | None:
    """Half of ``$WATCHDOG_USEC`` in seconds, when it is set, positive and (with
    ``$WATCHDOG_PID``) meant for this process; else None."""
    try:
        usec = int(env.get("WATCHDOG_USEC", ""))
    except ValueError:
        return None
    pid = env.get("WATCHDOG_PID", "")
    if usec <= 0 or (pid and pid != str(os.getpid())):
        return None
    return usec / 2e6
