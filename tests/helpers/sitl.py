"""Process helpers for the end-to-end tests: firmware_sim and the daemon as separate processes.

Every process gets a timeout and is stopped by its own id (SIGINT, then SIGKILL).
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file, vehicle_file
from tests.helpers.repo import ROOT as REPO

BARREL = maneuver_file("barrel_roll")
VEHICLE = DEFAULT_VEHICLE
VEHICLE_IDEAL = vehicle_file("mk_quadro_ideal")
"""Ideal actuators in the emulator, and a controller that knows it (no lag to lead)."""
CONTROLLER = PAPER_CONTROLLER


class Proc:
    """A child process whose output lines are collected by a reader thread."""

    def __init__(self, cmd, cwd=REPO):
        self.cmd = cmd
        self.p = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True, bufsize=1)
        self.lines: list[str] = []
        self._cv = threading.Condition()
        self._t = threading.Thread(target=self._read, daemon=True)
        self._t.start()

    def _read(self):
        for line in self.p.stdout:
            with self._cv:
                self.lines.append(line.rstrip("\n"))
                self._cv.notify_all()
        with self._cv:
            self._cv.notify_all()

    def wait_line(self, needle: str, timeout_s: float, nth: int = 1) -> str:
        """The ``nth`` line that holds ``needle``, once printed (AssertionError after ``timeout_s``)."""
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while True:
                hits = [ln for ln in self.lines if needle in ln]
                if len(hits) >= nth:
                    return hits[nth - 1]
                left = deadline - time.monotonic()
                if left <= 0 or (self.p.poll() is not None and not self._t.is_alive()):
                    raise AssertionError(f"{needle!r} not seen from {self.cmd[:3]}; last lines:\n"
                                         + "\n".join(self.lines[-20:]))
                self._cv.wait(min(left, 0.5))

    def wait(self, timeout_s: float) -> int:
        try:
            return self.p.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.stop()
            raise AssertionError(f"{self.cmd[:3]} did not finish in {timeout_s} s; last lines:\n"
                                 + "\n".join(self.lines[-20:]))

    def stop(self, sig=signal.SIGINT, timeout_s: float = 20.0) -> int:
        if self.p.poll() is None:
            self.p.send_signal(sig)
            try:
                self.p.wait(timeout_s)
            except subprocess.TimeoutExpired:
                self.p.kill()
                self.p.wait()
        self._t.join(5)
        return self.p.returncode


def start_emulator(record: Path, *args: str) -> tuple[Proc, str]:
    """firmware_sim on a free loopback port; returns (process, the daemon's udpout URL)."""
    proc = Proc([sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", "--quiet",
                 "--record", str(record), *args])
    line = proc.wait_line("firmware_sim listening on", 30)
    return proc, line.split()[-1].replace("udpin:", "udpout:")


def free_udp_port() -> int:
    """A loopback UDP port free a moment ago (for a process that must listen on a known one)."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def mavreg(*args: str) -> Proc:
    return Proc([sys.executable, "-m", "mavreg.cli.main", *args])


def load_record(path: Path) -> dict:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def tilt_deg(q: np.ndarray) -> np.ndarray:
    """Angle between body z and NED z for quaternions (w, x, y, z)."""
    up = 1.0 - 2.0 * (q[:, 1] ** 2 + q[:, 2] ** 2)
    return np.degrees(np.arccos(np.clip(up, -1.0, 1.0)))


def env_without_display() -> dict:
    env = dict(os.environ)
    env["MPLBACKEND"] = "Agg"
    return env


def flight_modes(tlog: Path) -> tuple[list[str], dict]:
    """``mavflightmodes.py`` (pymavlink's tool) on a .tlog: the modes in the order it saw them,
    and its "Time per mode" table, name -> (seconds as it prints them, whole; share of the log)."""
    res = subprocess.run(["mavflightmodes.py", str(tlog)], capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    changes = [ln.split("MAV.flightmode=")[1].split()[0] for ln in res.stdout.splitlines() if "flightmode=" in ln]
    words = res.stdout.split("Time per mode:")[1].split()
    table = {}
    for name, hms, share in zip(words[::3], words[1::3], words[2::3]):
        h, m, s = (int(x) for x in hms.split(":"))
        table[name] = (3600 * h + 60 * m + s, float(share.rstrip("%")) / 100.0)
    return changes, table


def vehicle_samples(tlog: Path) -> np.ndarray:
    """(N, 2): the .tlog's time stamp (s) and the vehicle's time (s) of each LOCAL_POSITION_NED."""
    from pymavlink import mavutil
    conn = mavutil.mavlink_connection(str(tlog))
    rows = []
    while (m := conn.recv_match(type="LOCAL_POSITION_NED")) is not None:
        rows.append((m._timestamp, m.time_boot_ms / 1000.0))
    return np.array(rows)


RECORD_FIELDS = ("result", "reason", "first_bound", "bound_phase", "action", "maneuver_max_error_m",
                 "loop_max_error_m", "max_attitude_error_deg", "overspeed_m_s", "lowest_altitude_m",
                 "max_touchdown_speed_m_s", "ground_impact", "motors_stopped_in_air", "motors_stopped_event_t_s",
                 "flight_time_s", "safety", "cause", "seed", "emulator_args")
"""The fields of every flight record of ``mavreg experiment robustness`` (results.json)."""
