"""A stock autopilot's MAVLink link as the test harnesses speak it: receive, wait by messages,
commands, message rates and parameters.

:class:`SitlLink` is what :class:`~tests.helpers.ardupilot_sitl.ArduPilotSitl` and
:class:`~tests.helpers.px4_sitl.Px4Sitl` share: a pymavlink connection (``conn``) to the
autopilot, a ground-station HEARTBEAT a second on it, every STATUSTEXT kept with its time, and
waits bounded by time that end in :class:`SitlError` with the autopilot's last words. A
subclass names the autopilot (``name``), checks that its process lives (``_check_alive``) and
says what it printed last (``output_tail``).
"""
from __future__ import annotations

import os
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402  (MAVLINK20 must be set first)

__all__ = ["SitlLink", "SitlError", "SitlExitedEarly", "M", "mavutil"]

M = mavutil.mavlink
PREARM_BIT = M.MAV_SYS_STATUS_PREARM_CHECK


class SitlError(RuntimeError):
    """The SITL did not start, answer or become ready in time (one line, with its last texts)."""


class SitlExitedEarly(SitlError):
    """The SITL process ended while the harness waited for it."""


class SitlLink:
    """The MAVLink side of a SITL harness (a mixin: the subclass opens ``conn`` and sets ``t0``)."""

    name = "SITL"

    def _init_link(self) -> None:
        self.conn = None
        self.t0 = 0.0
        self.sysid = 1
        self.compid = 1
        self._last_hb = -1e9
        self.texts: list[tuple[float, str]] = []
        """(seconds since start, STATUSTEXT) of everything seen by :meth:`recv`."""
        self.first_seen: dict[str, float] = {}
        """Message type -> seconds since start when :meth:`recv` first saw it."""
        self.prearm_ok = False
        """The pre-arm health bit of the latest SYS_STATUS."""

    def elapsed_s(self) -> float:
        return time.monotonic() - self.t0

    def recv(self, timeout_s: float = 0.1):
        """The next message from the vehicle (None on timeout); STATUSTEXTs are recorded.

        Sends a ground-station HEARTBEAT every second on the way."""
        now = time.monotonic()
        if now - self._last_hb >= 1.0:
            self._last_hb = now
            self.conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        m = self.conn.recv_match(blocking=True, timeout=timeout_s)
        if m is None or m.get_type() == "BAD_DATA":
            return None
        mtype = m.get_type()
        self.first_seen.setdefault(mtype, self.elapsed_s())
        if mtype == "STATUSTEXT":
            self.texts.append((self.elapsed_s(), m.text))
        elif mtype == "SYS_STATUS":
            self.prearm_ok = bool(m.onboard_control_sensors_health & PREARM_BIT)
        return m

    def wait_until(self, cond, timeout_s: float, what: str) -> None:
        """Receive until ``cond()`` holds; :class:`SitlError` after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while not cond():
            if time.monotonic() > deadline:
                raise self._timeout(what, timeout_s)
            self._check_alive(what)
            self.recv(0.2)

    def wait_for(self, pred, timeout_s: float, what: str):
        """The first message satisfying ``pred``; :class:`SitlError` after ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self._check_alive(what)
            m = self.recv(0.2)
            if m is not None and pred(m):
                return m
        raise self._timeout(what, timeout_s)

    def _timeout(self, what: str, timeout_s: float) -> SitlError:
        last = "; ".join(t for _, t in self.texts[-3:])
        return SitlError(f"{self.name}: no {what} within {timeout_s:.0f} s (last texts: {last}; "
                         f"last output: {self.output_tail()})")

    def send(self, msg) -> None:
        self.conn.mav.send(msg)

    def command_long(self, command: int, *params: float, timeout_s: float = 3.0):
        """Send a COMMAND_LONG and return its COMMAND_ACK (SitlError if none)."""
        p = [float(v) for v in params] + [0.0] * (7 - len(params))
        self.conn.mav.command_long_send(self.sysid, self.compid, command, 0, *p)
        return self.wait_for(lambda m: m.get_type() == "COMMAND_ACK" and m.command == command,
                             timeout_s, f"COMMAND_ACK of command {command}")

    def set_rate(self, msg_id: int, hz: float) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL; returns the ACK's result."""
        ack = self.command_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz if hz > 0 else -1)
        return int(ack.result)

    def _param_value(self, name: str, timeout_s: float, what: str):
        return self.wait_for(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name, timeout_s, what)

    def _check_alive(self, what: str) -> None:
        """Raise :class:`SitlExitedEarly` when the autopilot's process has ended."""

    def output_tail(self, lines: int = 3) -> str:
        """The last lines the autopilot printed."""
        return "(none)"
