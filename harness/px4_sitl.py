"""A stock PX4 SITL (SIH, PX4's in-process simulator) as a test fixture: start, configure over
MAVLink, record its ground truth, stop.

The directory (``$MAVREG_PX4_DIR``, else ``shared/autopilot/px4`` beside the repository) holds
PX4 v1.16's ``bin/px4``, its ``etc/`` and a ``start.sh`` that starts it headless on an
``INSTANCE`` and prints its PID (its README). Instance ``i`` fixes the ports and the system id:

- the offboard link (PX4's ``onboard`` MAVLink instance) sends to 127.0.0.1:14540 + i, where
  the harness (and then mavreg) listens, and listens on 14580 + i;
- SIH's display link sends ``HIL_STATE_QUATERNION`` (the simulator's true state) from
  19450 + i to 127.0.0.1:19410 + i, where :class:`TruthRecorder` listens;
- the system id is 1 + i (``MAV_SYS_ID``).

PX4's rc script calls its modules as ``px4-<module>``, links to ``bin/px4``. Where the
directory was copied without its links (each ``px4-*`` a small file naming ``px4``), the
harness makes the links in a directory of its own and puts it first on ``PATH``; start.sh runs
as it is. Parameters are set over MAVLink only (integers with their bytes in the float field,
``MAV_PARAM_TYPE_INT32``, as PX4 does), before arming; SIH's airframe parameters (``SIH_*``)
take effect at once. The harness waits by messages, never by sleeps: the first HEARTBEAT, then
``LOCAL_POSITION_NED``, EKF2's origin and the pre-arm checks passing.
"""
from __future__ import annotations

import math
import os
import socket
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest


from .ardupilot_mocap import ned_m
from .processes import alive as _alive
from .processes import terminate as _terminate
from .sitl_link import M, SitlError, SitlExitedEarly, SitlLink, autopilot_dir, mavutil

__all__ = ["px4_dir", "require_px4", "Px4Sitl", "TruthRecorder", "SitlError", "PX4_INT_PARAMS",
           "PILOT_PARAMS", "TRUTH_RATE_HZ"]

ENV_VAR = "MAVREG_PX4_DIR"
TRUTH_RATE_HZ = 100.0
"""HIL_STATE_QUATERNION's rate asked for on SIH's display link (25 Hz by default)."""
PX4_INT_PARAMS = frozenset({"COM_OBL_RC_ACT", "MAV_SYS_ID", "COM_RCL_EXCEPT", "NAV_RCL_ACT", "NAV_DLL_ACT",
                            "COM_ARM_WO_GPS", "CBRK_SUPPLY_CHK", "COM_DISARM_PRFLT", "EKF2_GPS_CTRL",
                            "EKF2_EV_CTRL", "EKF2_HGT_REF", "EKF2_BARO_CTRL", "EKF2_MAG_TYPE",
                            "EKF2_EV_NOISE_MD", "SYS_HAS_MAG", "MC_AIRMODE"})
"""PX4 parameters of integer type that a harness sets (their bytes travel in the float)."""
MOCAP_PARAMS = {"EKF2_EV_CTRL": 15, "EKF2_HGT_REF": 3, "EKF2_GPS_CTRL": 0, "EKF2_BARO_CTRL": 0,
                "EKF2_MAG_TYPE": 5, "EKF2_EV_DELAY": 5.0, "EKF2_EV_NOISE_MD": 1, "EKF2_EVP_NOISE": 0.01,
                "EKF2_EVV_NOISE": 0.03, "EKF2_EVA_NOISE": 0.03}
"""EKF2 on a motion-capture system (external vision: position, velocity and yaw; height from
it, not from the barometer; no GPS, no magnetometer), as a lab sets it up; its delay is the
feed's loopback and PX4's stream scheduling, a few milliseconds."""
POSITION_SOURCES = ("gps", "mocap")
PILOT_PARAMS: dict = {}
"""What docs/autopilots.md tells a pilot to set on PX4 before flying mavreg: nothing, PX4's
defaults pass mavreg's checks (``COM_OF_LOSS_T`` 1 s, ``COM_OBL_RC_ACT`` 0 Position)."""


def px4_dir() -> Path | None:
    """The PX4 SITL directory, or None: ``$MAVREG_PX4_DIR`` when set; else ``shared/autopilot/px4``
    beside the repository (:func:`~harness.sitl_link.autopilot_dir`)."""
    return autopilot_dir(ENV_VAR, "px4", ("start.sh", "bin/px4"))


def require_px4() -> Path:
    """The PX4 SITL directory, or skip the calling test with a clear message."""
    d = px4_dir()
    if d is None:
        pytest.skip(f"PX4 SITL not found: set {ENV_VAR} to a directory holding start.sh and bin/px4 "
                    "(PX4 v1.16 built for px4_sitl_default, with its etc/)")
    return d


def _instance_free(i: int) -> bool:
    """Every UDP port instance ``i`` binds or sends to is free on the loopback."""
    for port in (14540 + i, 14580 + i, 18570 + i, 19410 + i, 19450 + i):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                return False
    return True


def free_instance(first: int = 0, last: int = 9) -> int:
    for i in range(first, last + 1):
        if _instance_free(i):
            return i
    raise SitlError(f"no free PX4 instance in {first}..{last} (UDP 14540+i, 14580+i, 19410+i all taken)")


def module_links(directory: Path, into: Path) -> Path | None:
    """A directory of ``px4-<module>`` links to ``bin/px4`` when ``directory``'s are not links
    (a copy that flattened them), else None."""
    bindir = directory / "bin"
    stubs = [p for p in bindir.glob("px4-*") if p.name != "px4-alias.sh"]
    if not stubs or all(p.is_symlink() or os.access(p, os.X_OK) for p in stubs):
        return None
    into.mkdir(parents=True, exist_ok=True)
    for p in stubs:
        (into / p.name).symlink_to(bindir / "px4")
    return into


class TruthRecorder:
    """SIH's true state, ``HIL_STATE_QUATERNION``, recorded from its display link in a thread.

    Rows: the wall clock at arrival (s; SIH sends ``time_usec`` 0, and the daemon's tlog stamps
    its frames with the same clock, which maps them onto PX4's boot time), latitude
    and longitude (deg), altitude (m), the quaternion (w, x, y, z), NED velocity (m/s).
    :attr:`rates`: the wall clock at arrival and the true body rates (rad/s, FRD) of each.
    """

    def __init__(self, instance: int, system_id: int, rate_hz: float = TRUTH_RATE_HZ, feed: bool = False):
        self.port = 19410 + instance
        self.system_id = system_id
        self.rate_hz = rate_hz
        self.feed = feed
        """Send each sample back at once as ``ODOMETRY`` (estimator type VISION): a
        motion-capture system for EKF2 (:data:`MOCAP_PARAMS`), NED about :attr:`home`."""
        self.home: tuple[float, float, float] | None = None
        """The first sample's latitude, longitude (deg) and altitude (m): the vehicle on the
        ground at boot, the origin of the motion-capture frame."""
        self.rows: list[tuple] = []
        self.feed_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
        """Added to the position fed to EKF2 (NED, m): a fault test's glitch."""
        self.rates: list[tuple] = []
        self._stop = threading.Event()
        self._conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}", source_system=255,
                                                source_component=191, dialect="common")
        self._thread = threading.Thread(target=self._run, name="px4-truth", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _run(self) -> None:
        asked = -1e9
        while not self._stop.is_set():
            now = time.monotonic()
            recent = sum(1 for r in self.rows[-int(self.rate_hz):] if r[0] > time.time() - 1.0)
            if now - asked > 2.0 and recent < 0.8 * self.rate_hz:
                asked = now             # until it streams at the rate (a request before PX4 is up is lost)
                self._conn.mav.command_long_send(self.system_id, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                                 M.MAVLINK_MSG_ID_HIL_STATE_QUATERNION, 1e6 / self.rate_hz,
                                                 0, 0, 0, 0, 0)
            m = self._conn.recv_match(type="HIL_STATE_QUATERNION", blocking=True, timeout=0.2)
            if m is not None:      # SIH leaves time_usec 0: stamped on arrival, by the wall clock
                row = (time.time(), m.lat * 1e-7, m.lon * 1e-7, m.alt * 1e-3,
                       *m.attitude_quaternion, m.vx * 0.01, m.vy * 0.01, m.vz * 0.01)
                self.rows.append(row)
                self.rates.append((row[0], m.rollspeed, m.pitchspeed, m.yawspeed))
                if self.home is None:
                    self.home = row[1:4]
                if self.feed:
                    self._send_odometry(row)

    def _send_odometry(self, row: tuple) -> None:
        """The sample as ODOMETRY: position and velocity NED about :attr:`home`, the attitude
        body to NED; ``time_usec`` 0, which PX4 stamps with its arrival (this link answers no
        TIMESYNC, so PX4's time sync never converges on it); covariances unknown (NaN: PX4 takes
        ``EKF2_EVP_NOISE``, ``EKF2_EVV_NOISE``, ``EKF2_EVA_NOISE``)."""
        n, e, d = np.add(ned_m(row[1], row[2], row[3], self.home), self.feed_offset_m)
        nan21 = [math.nan] + [0.0] * 20
        self._conn.mav.odometry_send(0, M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_NED, n, e, d, list(row[4:8]),
                                     row[8], row[9], row[10], math.nan, math.nan, math.nan, nan21, nan21,
                                     0, M.MAV_ESTIMATOR_TYPE_VISION, 100)

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self._conn.close()

    def save(self, path: Path, origin: tuple[float, float, float]) -> Path:
        """Write ``truth.npz``: wall_time_s, position_ned_m about ``origin`` (lat, lon deg, alt m),
        quaternion_wxyz, velocity_ned_m_s."""
        rows = np.array(self.rows, dtype=float).reshape(-1, 11)
        pos = np.array([ned_m(r[1], r[2], r[3], origin) for r in rows]).reshape(-1, 3)
        np.savez(path, wall_time_s=rows[:, 0], position_ned_m=pos, quaternion_wxyz=rows[:, 4:8],
                 velocity_ned_m_s=rows[:, 8:11], origin=np.array(origin))
        return Path(path)


class Px4Sitl(SitlLink):
    """One PX4 SIH process, a pymavlink connection to its offboard link, and its truth.

    Parameters
    ----------
    params : dict
        Parameters set over MAVLink once it answers (``SIH_*`` for the airframe,
        ``COM_*``), e.g. ``{"SIH_T_MAX": 10.0}``; names in :data:`PX4_INT_PARAMS` as integers.
    instance : int or None
        PX4's instance (system id 1 + instance); the first free one from 0 by default.
    wait_ready : bool
        Wait for EKF2's local position, its origin and the pre-arm checks.
    timeout_s : float
        Bound on each wait.
    position_source : str
        EKF2's: ``gps`` (SIH's GPS and barometer, as the airframe has them) or ``mocap`` (the
        truth fed back as external vision at 100 Hz, :data:`MOCAP_PARAMS`).
    """

    name = "PX4 SITL"
    bytewise = True
    int_params = PX4_INT_PARAMS

    def __init__(self, params: dict | None = None, instance: int | None = None, wait_ready: bool = True,
                 timeout_s: float = 60.0, directory: Path | None = None, position_source: str = "gps"):
        if position_source not in POSITION_SOURCES:
            raise ValueError(f"position_source must be one of {POSITION_SOURCES}, not {position_source!r}")
        self._init_link()
        self.position_source = position_source
        self.params = {**(MOCAP_PARAMS if position_source == "mocap" else {}), **(params or {})}
        self.instance = instance
        self.wait_ready = wait_ready
        self.timeout_s = float(timeout_s)
        self.directory = directory or px4_dir()
        self.pid: int | None = None
        self.workdir: tempfile.TemporaryDirectory | None = None
        self.truth: TruthRecorder | None = None
        self._origin_msg = None
        self.origin: tuple[float, float, float] | None = None
        """The local frame's origin (lat, lon deg, alt m): EKF2's on GPS (but for the barometer's
        height), the vehicle at boot on motion capture."""

    @property
    def port(self) -> int:
        """The UDP port PX4's offboard link sends to (``udpin:127.0.0.1:PORT`` for mavreg)."""
        return 14540 + self.instance

    def start(self) -> None:
        if self.directory is None:
            raise SitlError(f"PX4 SITL not found (set {ENV_VAR})")
        if self.instance is None:
            self.instance = free_instance()
        self.take_link()
        self.truth = TruthRecorder(self.instance, 1 + self.instance, feed=self.position_source == "mocap")
        self.t0 = time.monotonic()
        self._launch()
        hb = self.wait_for(lambda m: m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1
                           and m.autopilot == M.MAV_AUTOPILOT_PX4, self.timeout_s, "first HEARTBEAT")
        self.sysid, self.compid = hb.get_srcSystem(), hb.get_srcComponent()
        self.conn.target_system, self.conn.target_component = self.sysid, self.compid
        self.truth.start()
        for name, value in self.params.items():
            self.set_param(name, value)
        if self.wait_ready:
            self.set_rate(M.MAVLINK_MSG_ID_SYS_STATUS, 2.0)
            self.wait_until(lambda: "LOCAL_POSITION_NED" in self.first_seen, self.timeout_s, "local position")
            self.wait_until(lambda: self.prearm_ok, self.timeout_s, "pre-arm checks passing")
            # with motion capture EKF2's frame is the feed's, about the vehicle at boot
            self.origin = self._ekf_origin() if self.position_source == "gps" else self.truth.home

    def _ekf_origin(self) -> tuple[float, float, float]:
        """EKF2's origin (lat, lon deg, alt m), asked for until it answers: EKF2 sets it once
        GPS is fused, which may come after its first local position."""
        deadline = time.monotonic() + self.timeout_s
        while self._origin_msg is None:
            self.command_long(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)
            try:             # PX4 sends it before its COMMAND_ACK: recv keeps it on the way
                self.wait_until(lambda: self._origin_msg is not None, 2.0, "GPS_GLOBAL_ORIGIN")
            except SitlError:
                if time.monotonic() > deadline:
                    raise
        o = self._origin_msg
        return (o.latitude * 1e-7, o.longitude * 1e-7, o.altitude * 1e-3)

    def recv(self, timeout_s: float = 0.1):
        """:meth:`SitlLink.recv`, keeping the latest GPS_GLOBAL_ORIGIN."""
        m = super().recv(timeout_s)
        if m is not None and m.get_type() == "GPS_GLOBAL_ORIGIN":
            self._origin_msg = m
        return m

    def _launch(self) -> None:
        self.workdir = tempfile.TemporaryDirectory(prefix="mavreg-px4-")
        work = Path(self.workdir.name)
        env = dict(os.environ, INSTANCE=str(self.instance), WORKDIR=str(work / "px4"))
        links = module_links(self.directory, work / "bin")
        if links is not None:
            env["PATH"] = f"{links}{os.pathsep}{env.get('PATH', '')}"
        out = subprocess.run([str(self.directory / "start.sh")], env=env, capture_output=True, text=True,
                             timeout=30)
        if out.returncode != 0 or not out.stdout.strip().isdigit():
            raise SitlError(f"PX4 start.sh failed ({out.returncode}): {out.stderr.strip()[-200:]}")
        self.pid = int(out.stdout.strip())

    def stop(self) -> None:
        """Stop the truth, SIGTERM PX4 by its PID (SIGKILL after 10 s), close the link."""
        if self.truth is not None:
            self.truth.stop()
        if self.pid is not None:
            _terminate(self.pid)
            self.pid = None
        if self.conn is not None:
            self.conn.close()
            self.conn = None

    def cleanup(self) -> None:
        """Remove the working directory (parameters, ``.ulg`` logs); after :meth:`stop`."""
        if self.workdir is not None:
            self.workdir.cleanup()
            self.workdir = None

    def finish(self, out: Path) -> None:
        """End the run into ``out``: stop PX4, write its truth (``truth.npz``), keep PX4's own
        ``.ulg`` logs beside it, remove the working directory."""
        import shutil
        self.stop()
        self.truth.save(Path(out) / "truth.npz", self.origin)
        for ulg in self.ulogs():
            shutil.copy(ulg, Path(out) / ulg.name)
        self.cleanup()

    def ulogs(self) -> list[Path]:
        """PX4's own flight logs of this run (``.ulg``)."""
        if self.workdir is None:
            return []
        return sorted((Path(self.workdir.name) / "px4" / "log").rglob("*.ulg"))

    def take_link(self) -> None:
        """Listen on PX4's offboard link as a ground station (again, once mavreg is gone)."""
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}", source_system=255,
                                               source_component=190, dialect="common")

    def _check_alive(self, what: str) -> None:
        if self.pid is not None and not _alive(self.pid):
            self.pid = None
            raise SitlExitedEarly(f"PX4 SITL exited while waiting for {what}; its last output: "
                                  f"{self.output_tail()}")

    def output_tail(self, lines: int = 3) -> str:
        try:
            text = (Path(self.workdir.name) / "px4" / "px4.out").read_text(errors="replace")
        except (OSError, AttributeError):
            return "(none)"
        return " | ".join(text.strip().splitlines()[-lines:]) or "(none)"

