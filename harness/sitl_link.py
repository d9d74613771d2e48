"""A stock autopilot's MAVLink link as the test harnesses speak it: receive, wait by messages,
commands, message rates and parameters.

:class:`SitlLink` is what :class:`~harness.ardupilot_sitl.ArduPilotSitl` and
:class:`~harness.px4_sitl.Px4Sitl` share: a pymavlink connection (``conn``) to the
autopilot, a ground-station HEARTBEAT a second on it, every STATUSTEXT kept with its time, and
waits bounded by time that end in :class:`SitlError` with the autopilot's last words. A
subclass names the autopilot (``name``), checks that its process lives (``_check_alive``) and
says what it printed last (``output_tail``).
"""
from __future__ import annotations

import os
import struct
import time
from pathlib import Path

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402  (MAVLINK20 must be set first)

from mavreg.daemon.vehicle.autopilots import param_value  # noqa: E402

__all__ = ["SitlLink", "SitlError", "SitlExitedEarly", "M", "mavutil", "autopilot_dir", "parse_param_items"]

REPO = Path(__file__).resolve().parents[1]

M = mavutil.mavlink
PREARM_BIT = M.MAV_SYS_STATUS_PREARM_CHECK


def autopilot_dir(env_var: str, name: str, files: tuple[str, ...]) -> Path | None:
    """A stock autopilot's SITL directory, or None: ``$env_var`` when set; else
    ``shared/autopilot/<name>`` in the directory that holds the repository (or the main
    checkout, when this is a git worktree); it must hold every one of ``files``."""
    env = os.environ.get(env_var)
    roots = [REPO]
    git = REPO / ".git"
    if git.is_file() and git.read_text().startswith("gitdir:"):   # a worktree: .git names the main one's
        roots.append(Path(git.read_text().split(":", 1)[1].strip()).parents[2])
    for d in [Path(env)] if env else [r / ".." / "shared" / "autopilot" / name for r in roots]:
        if all((d / f).is_file() for f in files):
            return d.resolve()
    return None


def parse_param_items(parser, items) -> dict:
    """``NAME=VALUE`` command-line items as {name: float}; a malformed one is the parser's error."""
    params = {}
    for item in items:
        name, _, value = item.partition("=")
        try:
            params[name.strip()] = float(value)
        except ValueError:
            parser.error(f"--param {item!r}: want NAME=VALUE with a number")
    return params


class SitlError(RuntimeError):
    """The SITL did not start, answer or become ready in time (one line, with its last texts)."""


class SitlExitedEarly(SitlError):
    """The SITL process ended while the harness waited for it."""


class SitlLink:
    """The MAVLink side of a SITL harness (a mixin: the subclass opens ``conn`` and sets ``t0``)."""

    name = "SITL"
    bytewise = False
    """Integer parameters arrive with their bytes in PARAM_VALUE's float (PX4), not cast (ArduPilot)."""
    int_params: frozenset = frozenset()
    """Parameters :meth:`set_param` sends as integers."""

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

    def release_link(self) -> int:
        """Close the harness's link so mavreg can take its port (the SITL keeps sending there);
        the port."""
        self.conn.close()
        self.conn = None
        return self.port

    def set_rate(self, msg_id: int, hz: float) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL; returns the ACK's result."""
        ack = self.command_long(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz if hz > 0 else -1)
        return int(ack.result)

    def _param_value(self, name: str, timeout_s: float, what: str):
        return self.wait_for(lambda m: m.get_type() == "PARAM_VALUE" and m.param_id == name, timeout_s, what)

    def get_param(self, name: str, timeout_s: float = 3.0) -> float:
        """PARAM_REQUEST_READ by name; the PARAM_VALUE's value (decoded as the autopilot sends
        integers: :attr:`bytewise`)."""
        self.conn.mav.param_request_read_send(self.sysid, self.compid, name.encode(), -1)
        return param_value(self._param_value(name, timeout_s, f"PARAM_VALUE {name}"), self.bytewise)

    def set_param(self, name: str, value: float, timeout_s: float = 3.0) -> None:
        """PARAM_SET, confirmed by the echoed PARAM_VALUE (test setup only). A name in
        :attr:`int_params` travels as an INT32 with its bytes in the float, as PX4 takes it."""
        if name in self.int_params:
            raw = struct.unpack("<f", struct.pack("<i", int(value)))[0]
            self.conn.mav.param_set_send(self.sysid, self.compid, name.encode(), raw, M.MAV_PARAM_TYPE_INT32)
        else:
            self.conn.mav.param_set_send(self.sysid, self.compid, name.encode(), float(value),
                                         M.MAV_PARAM_TYPE_REAL32)
        got = param_value(self._param_value(name, timeout_s, f"PARAM_VALUE echo of {name}"), self.bytewise)
        if abs(got - float(value)) > 1e-6 * max(1.0, abs(float(value))):
            raise SitlError(f"{self.name}: {name} is {got} after setting {value}")

    # -- life cycle (the subclass's start and stop) -----------------------------------------
    def __enter__(self):
        try:
            self.start()
        except BaseException:
            self.stop()
            raise
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _check_alive(self, what: str) -> None:
        """Raise :class:`SitlExitedEarly` when the autopilot's process has ended."""

    def output_tail(self, lines: int = 3) -> str:
        """The last lines the autopilot printed."""
        return "(none)"


def fly_into_the_maneuver(cmd: list[str], log: Path, after_s: float, wait_s: float = 120.0):
    """Start ``cmd`` (a ``mavreg fly``; its output into ``log``, never a pipe that could fill)
    and return (process, still flying) ``after_s`` (wall clock) after the daemon said the
    maneuver began, or at once where it ended or did not get there within ``wait_s``."""
    import subprocess
    with open(log, "w") as f:
        proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, text=True)
    end = time.monotonic() + wait_s
    while "[maneuver] phase" not in Path(log).read_text():    # the daemon's own word that it began
        if proc.poll() is not None or time.monotonic() > end:
            return proc, False
        time.sleep(0.05)
    deadline = time.monotonic() + after_s
    while time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)                  # the scenario's timing (the fault's moment), not a wait for a state
    return proc, proc.poll() is None
