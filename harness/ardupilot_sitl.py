"""A stock ArduCopter SITL as a test fixture: start, configure over MAVLink, wait, stop.

The SITL directory holds ArduPilot's ``arducopter`` SITL binary and a ``start.sh`` that
starts it headless with a ``FRAME`` and a ``MAVLINK`` address and prints its PID (the same
layout the measurements of ``docs/autopilots.md`` used). It is found through the
environment variable ``MAVREG_ARDUPILOT_DIR``, else in ``shared/autopilot/ardupilot`` next to
the repository's directory; tests that need it are skipped when it is absent.

:class:`ArduPilotSitl` starts the SITL on a free loopback UDP port (the harness listens
first, then the SITL sends there) and a free instance number (each instance binds a fixed
UDP port, ``5501 + 10 * instance``), sets parameters over MAVLink (``PARAM_SET``, confirmed by
the echoed ``PARAM_VALUE``), asks for telemetry rates, and waits by messages, never by
sleeps: the first HEARTBEAT, then the first ``LOCAL_POSITION_NED`` (sent once EKF3 uses GPS,
about 20 s after it set its origin; GUIDED refuses to arm before: "Need Position Estimate") and
the pre-arm checks passing (``SYS_STATUS`` health bit ``MAV_SYS_STATUS_PREARM_CHECK``). It stops
the SITL by its PID (SIGTERM, then SIGKILL) on leaving the ``with`` block, also on failure.
"""
from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import pytest

from .ardupilot_mocap import HOME, MocapFeed
from .processes import alive as _alive
from .processes import terminate as _terminate
from .sitl_link import M, SitlError, SitlExitedEarly, SitlLink, autopilot_dir, mavutil

__all__ = ["ardupilot_dir", "ArduPilotSitl", "GroundLink", "SitlError", "require_ardupilot", "arducopter_sitl_fixture",
           "TEST_PARAMS", "POSITION_SOURCES", "HOME"]

ENV_VAR = "MAVREG_ARDUPILOT_DIR"
START_ATTEMPTS = 6
"""start.sh's exit races with the SITL's start (see ``ArduPilotSitl._launch``): about 1 in 4
starts die at once; six attempts all fail about once in 4000."""
POSITION_SOURCES = ("gps", "vicon", "mocap")
"""Where ArduCopter's EKF3 takes its position from: its simulated GPS (5 Hz, the frame's
defaults), the SITL's simulated Vicon or the harness's motion-capture feed
(:class:`~harness.ardupilot_mocap.MocapFeed`), both as ExternalNav (:data:`EXTRA_DEFAULTS`);
with either, the EKF's local frame is the vision frame, about :data:`HOME`."""
EXTRA_DEFAULTS = {"vicon": Path(__file__).with_name("ardupilot_vicon.parm"),
                  "mocap": Path(__file__).with_name("ardupilot_mocap.parm")}


def ardupilot_dir() -> Path | None:
    """The SITL directory, or None: ``$MAVREG_ARDUPILOT_DIR`` when set; else
    ``shared/autopilot/ardupilot`` beside the repository (:func:`~harness.sitl_link.autopilot_dir`)."""
    return autopilot_dir(ENV_VAR, "ardupilot", ("start.sh", "arducopter"))


def require_ardupilot() -> Path:
    """The SITL directory, or skip the calling test with a clear message."""
    d = ardupilot_dir()
    if d is None:
        pytest.skip(f"ArduCopter SITL not found: set {ENV_VAR} to a directory holding "
                    "start.sh and arducopter")
    return d


TEST_PARAMS = {"GUID_OPTIONS": 8, "GUID_TIMEOUT": 0.5, "ATC_ANGLE_BOOST": 0}
"""What mavreg's parameter check requires, set by the tests' own setup (mavreg never sets them)."""


@pytest.fixture(name="arducopter_sitl")
def arducopter_sitl_fixture():
    """Fixture ``arducopter_sitl``: a freestyle ArduCopter SITL with :data:`TEST_PARAMS`, ready
    to arm; stopped afterwards. Import ``arducopter_sitl_fixture`` into a test module to use it;
    skips when the SITL is absent."""
    require_ardupilot()
    with ArduPilotSitl(frame="freestyle", params=TEST_PARAMS) as sitl:
        yield sitl


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def free_instance(first: int = 1, last: int = 60) -> int:
    """A SITL instance number whose fixed port is free.

    Each instance binds UDP ``5501 + 10 * instance`` on all interfaces (its RC input); a
    free one keeps two SITLs (ours and anybody's) from sharing it."""
    for instance in range(first, last + 1):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("0.0.0.0", 5501 + 10 * instance))
            except OSError:
                continue
            return instance
    raise SitlError(f"no free SITL instance in {first}..{last} (UDP ports 5501 + 10 * instance all taken)")


class ArduPilotSitl(SitlLink):
    """One ArduCopter SITL process and a pymavlink connection to it (:class:`SitlLink`).

    Parameters
    ----------
    frame : str
        ``freestyle`` (0.8 kg 5-inch quad) or ``quad`` (3 kg default quad).
    params : dict
        Parameters set over MAVLink once it answers, e.g. ``{"GUID_OPTIONS": 8}``.
    rates_hz : dict
        Message id -> rate asked for with ``MAV_CMD_SET_MESSAGE_INTERVAL``.
    wait_ready : bool
        Wait for EKF origin and passing pre-arm checks before returning from ``start``.
    timeout_s : float
        Bound on each wait (heartbeat, each parameter, readiness).
    directory : Path
        The SITL directory; :func:`ardupilot_dir` by default.
    position_source : str
        ``gps`` (start.sh as it is), ``vicon`` or ``mocap``: the binary started as start.sh
        starts it, with :data:`EXTRA_DEFAULTS` after the frame's defaults, and the simulated Vicon
        on SERIAL5 (``vicon``) or the motion-capture feed on SERIAL1 (``mocap``).
    ground_link : bool
        Listen on SERIAL1 (start.sh's ``MAVLINK2``) as a second ground station,
        :attr:`ground` (:class:`GroundLink`), from before the start: the link that stays the
        test's once the first is handed to mavreg (not with ``mocap``, whose feed is SERIAL1).
    """

    name = "ArduCopter SITL"

    def __init__(self, frame: str = "freestyle", params: dict | None = None,
                 rates_hz: dict | None = None, wait_ready: bool = True, timeout_s: float = 90.0,
                 directory: Path | None = None, position_source: str = "gps", ground_link: bool = False):
        if position_source not in POSITION_SOURCES:
            raise ValueError(f"position_source must be one of {POSITION_SOURCES}, not {position_source!r}")
        if ground_link and position_source == "mocap":
            raise ValueError("ground_link needs SERIAL1, which the mocap feed takes")
        self.ground_link = ground_link
        self.ground: GroundLink | None = None
        """The second ground station on SERIAL1 (``ground_link``), from :meth:`start` to :meth:`stop`."""
        self.position_source = position_source
        self._proc: subprocess.Popen | None = None
        self.feed: MocapFeed | None = None
        """The motion-capture feed (``mocap``), running from launch to :meth:`stop`."""
        self.frame = frame
        self.params = dict(params or {})
        self.rates_hz = dict(rates_hz or {})
        self.wait_ready = wait_ready
        self.timeout_s = float(timeout_s)
        self.directory = directory or ardupilot_dir()
        self._init_link()
        self.pid: int | None = None
        self.port: int | None = None
        self.workdir: tempfile.TemporaryDirectory | None = None
        self.start_attempts = 0
        """start.sh runs it took (more than one when the SITL died at once)."""

    # -- life cycle -------------------------------------------------------------------------
    def start(self) -> None:
        """Start the SITL, configure it and (optionally) wait until it can arm."""
        if self.directory is None:
            raise SitlError(f"ArduCopter SITL not found (set {ENV_VAR})")
        self.port = free_udp_port()
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}", source_system=255,
                                               source_component=190, dialect="ardupilotmega")
        self.t0 = time.monotonic()
        if self.ground_link:
            self.ground = GroundLink(self, free_udp_port())
        for attempt in range(1, START_ATTEMPTS + 1):
            try:
                hb = self._launch()
                break
            except SitlExitedEarly:
                if attempt == START_ATTEMPTS:
                    raise
        self.start_attempts = attempt
        self.sysid, self.compid = hb.get_srcSystem(), hb.get_srcComponent()
        self.conn.target_system, self.conn.target_component = self.sysid, self.compid
        self.recv(0.0)                   # our first HEARTBEAT: ArduPilot sends STATUSTEXT only to active links
        if self.ground is not None:      # it answers where the SITL's first frame came from
            self.ground.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1,
                                 self.timeout_s, "first HEARTBEAT on SERIAL1")
        self.set_rate(M.MAVLINK_MSG_ID_SYS_STATUS, 2.0)      # not streamed by default
        for name, value in self.params.items():
            self.set_param(name, value)
        for msg_id, hz in self.rates_hz.items():
            self.set_rate(msg_id, hz)
        if self.wait_ready:
            if M.MAVLINK_MSG_ID_LOCAL_POSITION_NED not in self.rates_hz:
                self.set_rate(M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 10.0)
            self.wait_until(lambda: "LOCAL_POSITION_NED" in self.first_seen, self.timeout_s,
                            "local position (EKF using GPS)")
            self.wait_until(lambda: self.prearm_ok, self.timeout_s, "pre-arm checks passing")

    def _launch(self):
        """Run start.sh once; the first HEARTBEAT, or :class:`SitlExitedEarly`.

        start.sh starts the SITL in the background and exits at once. Measured: a SITL whose
        parent exits after its first moments exits too (start.sh kept alive for 1.2 s: 20 of 20
        died when it ended; start.sh as it is: 5 of 20 died within 0.3 s, never later). So a
        start either dies before the first heartbeat or not at all, and the caller starts again."""
        if self.workdir is not None:
            self.workdir.cleanup()
        self.workdir = tempfile.TemporaryDirectory(prefix="mavreg-ardupilot-")
        port2 = self.ground.port if self.ground is not None else free_udp_port()
        env = dict(os.environ, FRAME=self.frame, MAVLINK=f"udpclient:127.0.0.1:{self.port}",
                   MAVLINK2=f"udpclient:127.0.0.1:{port2}", WORKDIR=self.workdir.name,
                   INSTANCE=str(free_instance()))
        if self.position_source == "mocap" and self.feed is None:
            self.feed = MocapFeed(port2)
            self.feed.start()
            env["MAVLINK2"] = f"udpclient:127.0.0.1:{self.feed.port}"
        if self.position_source != "gps":
            self._start_with_defaults(env)
        else:
            out = subprocess.run([str(self.directory / "start.sh")], env=env, capture_output=True,
                                 text=True, timeout=30)
            if out.returncode != 0 or not out.stdout.strip().isdigit():
                raise SitlError(f"start.sh failed ({out.returncode}): {out.stderr.strip()[-200:]}")
            self.pid = int(out.stdout.strip())
        return self.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1,
                             self.timeout_s, "first HEARTBEAT")

    def _start_with_defaults(self, env: dict) -> None:
        """Start the binary as start.sh does (its frame, defaults and serial ports), plus
        :data:`EXTRA_DEFAULTS` after the frame's defaults and, for ``vicon``, the simulated Vicon
        on SERIAL5: start.sh takes no extra defaults, and VISO_TYPE and SERIALn_BAUD only take
        effect at boot. Our own child, so it does not share start.sh's early exit."""
        d, work, instance = self.directory, Path(env["WORKDIR"]), int(env["INSTANCE"])
        defaults = {"freestyle": ["copter.parm", "copter-X.parm", "freestyle.param"], "quad": ["copter.parm"]}
        if self.frame not in defaults:
            raise SitlError(f"frame must be one of {sorted(defaults)}, not {self.frame!r}")
        model = "quad"
        if self.frame == "freestyle":
            shutil.copy(d / "freestyle.json", work / "freestyle.json")   # the SITL reads it in its directory
            model = "X:freestyle.json"
        files = ",".join([str(d / f) for f in defaults[self.frame]] + [str(EXTRA_DEFAULTS[self.position_source])])
        cmd = [str(d / "arducopter"), "--model", model, "--speedup", "1", f"-I{instance}",
               "--home", ",".join(repr(v) for v in HOME) + ",0", "--defaults", files, "--wipe",
               "--serial0", env["MAVLINK"], "--serial1", env["MAVLINK2"],
               "--serial2", f"udpclient:127.0.0.1:{14701 + 10 * instance}"]
        if self.position_source == "vicon":
            cmd += ["--serial5", "sim:vicon:"]
        with open(work / "arducopter.out", "wb") as log:
            self._proc = subprocess.Popen(cmd, cwd=work, stdout=log, stderr=subprocess.STDOUT,
                                          stdin=subprocess.DEVNULL)
        self.pid = self._proc.pid

    def stop(self) -> None:
        """SIGTERM the SITL by its PID, SIGKILL after 10 s; close the link; remove its files."""
        if self.pid is not None:
            _terminate(self.pid)
            self.pid = None
        if self._proc is not None:
            self._proc.wait(timeout=5)          # our child (mocap): reap it
            self._proc = None
        if self.feed is not None:
            self.feed.stop()
            self.feed = None
        if self.ground is not None:
            self.ground.close()
            self.ground = None
        if self.conn is not None:
            self.conn.close()
            self.conn = None
        if self.workdir is not None:
            self.workdir.cleanup()
            self.workdir = None

    def _check_alive(self, what: str) -> None:
        if self.pid is not None:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:          # not our child (start.sh's): probe it
                pid, status = 0, 0
                if not _alive(self.pid):
                    pid = self.pid
            if pid == self.pid:
                self.pid = None
                raise SitlExitedEarly(f"ArduCopter SITL exited (status {status}) while waiting for {what}; "
                                f"its last output: {self.output_tail()}")

    def output_tail(self, lines: int = 3) -> str:
        """The last lines the SITL printed (its ``arducopter.out``), joined by " | "."""
        try:
            text = (Path(self.workdir.name) / "arducopter.out").read_text(errors="replace")
        except (OSError, AttributeError):
            return "(none)"
        return " | ".join(text.strip().splitlines()[-lines:]) or "(none)"



class GroundLink(SitlLink):
    """A second ground station on the SITL's SERIAL1 (:class:`ArduPilotSitl` with ``ground_link``).

    The SITL's first link is mavreg's once handed over; on this one a test speaks to the
    autopilot as a pilot's ground station would (commands, parameters, message rates: the
    :class:`SitlLink` methods) and keeps the SITL's true state: every ``SIM_STATE`` its
    :meth:`recv` sees is kept in :attr:`sim_state` as (wall s, altitude m, vn, ve, vd m/s).
    :meth:`pump` reads on in a thread between the test's own exchanges, which hold
    :attr:`lock`. A reboot keeps the link: the SITL sends to the same port again.
    """

    name = "ArduCopter SITL (SERIAL1)"

    def __init__(self, sitl: ArduPilotSitl, port: int):
        self._init_link()
        self.sitl = sitl
        self.port = port
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255,
                                               source_component=190, dialect="ardupilotmega")
        self.t0 = time.monotonic()
        self.sim_state: list[tuple[float, float, float, float, float]] = []
        self.lock = threading.RLock()
        self._pumping: threading.Thread | None = None
        self._stop = threading.Event()

    def recv(self, timeout_s: float = 0.1):
        with self.lock:
            m = super().recv(timeout_s)
        if m is not None and m.get_type() == "SIM_STATE":
            self.sim_state.append((time.monotonic(), m.alt, m.vn, m.ve, m.vd))
        return m

    def command_long(self, command: int, *params: float, timeout_s: float = 3.0):
        with self.lock:                  # the pump must not take the answer
            return super().command_long(command, *params, timeout_s=timeout_s)

    def get_param(self, name: str, timeout_s: float = 3.0) -> float:
        with self.lock:
            return super().get_param(name, timeout_s)

    def set_param(self, name: str, value: float, timeout_s: float = 3.0) -> None:
        with self.lock:
            super().set_param(name, value, timeout_s)

    def pump(self) -> None:
        """Read on in a daemon thread (until :meth:`close`), so that no SIM_STATE is missed and
        the ground station's HEARTBEAT keeps going."""
        def run():
            while not self._stop.is_set():
                with self.lock:
                    if self.conn is None:
                        return
                    self.recv(0.05)
        if self._pumping is None:
            self._pumping = threading.Thread(target=run, name="ground-link", daemon=True)
            self._pumping.start()

    def close(self) -> None:
        self._stop.set()
        if self._pumping is not None:
            self._pumping.join(5)
            self._pumping = None
        with self.lock:
            if self.conn is not None:
                self.conn.close()
                self.conn = None

    def _check_alive(self, what: str) -> None:
        self.sitl._check_alive(what)

    def output_tail(self, lines: int = 3) -> str:
        return self.sitl.output_tail(lines)
