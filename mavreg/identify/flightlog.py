"""Read a flight's telemetry and rotor commands for :mod:`mavreg.identify.fit`.

The I/O side of ``mavreg identify``: this module (and only this one in the package) reads
files and uses pymavlink. It turns a ``mavreg fly`` output directory or a bare ``.tlog``
into a :class:`~mavreg.identify.fit.FlightSeries` of plain arrays.

From the ``.tlog`` (every message in and out, in the order the daemon saw or sent it):

- the vehicle is the source of the first LOCAL_POSITION_NED or ATTITUDE_QUATERNION; its
  LOCAL_POSITION_NED and ATTITUDE_QUATERNION of one ``time_boot_ms`` make one sample;
- its HEARTBEATs give armed and the PX4 mode (OFFBOARD: main mode 6); each sample carries
  the status of the last HEARTBEAT before it;
- SET_ACTUATOR_CONTROL_TARGET (group 0) from any other source is a rotor command:
  ``controls[0..3]`` times the maximum rotor thrust. Each command is paired with the sample
  it answered: the daemon answers each complete sample with one command, sent right after
  it, so a command goes with the latest complete sample not answered yet. A command with no
  such sample (real time: sent across a telemetry gap) is placed on the vehicle clock by its
  ``time_usec`` (the daemon's clock) less the median offset of the paired commands;
- TIMESYNC: the daemon's request (``tc1 = 0``) follows the command of the sample it goes
  with; the vehicle's reply carries its clock (``tc1``, ns). ``tc1`` minus that sample's time
  is the sample-to-actuation delay of the link (:mod:`mavreg.daemon.timesync`); the median is
  returned.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import UsageError
from .regressors import FlightSeries

__all__ = ["read_flight", "read_tlog"]

_OFFBOARD_MAIN = 6
_ARMED_FLAG = 128


def read_flight(path: str | Path) -> FlightSeries:
    """A ``mavreg fly`` output directory (its ``flight.tlog``) or a ``.tlog`` file.

    Raises
    ------
    UsageError
        (a ValueError) One line: no such file, no ``flight.tlog`` in the directory, not a readable tlog, or
        a tlog without the messages the fit needs.
    """
    p = Path(path)
    if p.is_dir():
        tlog = p / "flight.tlog"
        if not tlog.is_file():
            raise UsageError(f"{p}: no flight.tlog in this directory (expected a 'mavreg fly' output)")
        return read_tlog(tlog)
    if not p.exists():
        raise UsageError(f"{p}: no such file or directory")
    return read_tlog(p)


def read_tlog(path: str | Path) -> FlightSeries:
    """Samples, commands and the TIMESYNC delay of one ``.tlog`` (see the module docstring)."""
    from pymavlink import mavutil
    path = Path(path)
    if not path.is_file():
        raise UsageError(f"{path}: no such file")
    try:
        conn = mavutil.mavlink_connection(str(path), dialect="common")
    except Exception as exc:    # pymavlink raises many kinds on a file that is not a tlog
        raise UsageError(f"{path}: cannot open as a tlog ({type(exc).__name__}: {exc})") from None
    try:
        return _parse(conn, path)
    finally:
        conn.close()


def _parse(conn, path: Path) -> FlightSeries:
    vehicle = None                      # (system, component) of the vehicle
    status: dict[tuple, bool] = {}      # source -> armed and in OFFBOARD, its last HEARTBEAT
    parts: dict[int, dict] = {}         # time_boot_ms -> {"att": msg, "pos": msg}
    rows: list[tuple] = []              # (t, p3, v3, q4, controlled)
    unanswered: float | None = None
    last_answered = math.nan
    cmd_t: list[float] = []
    cmd_usec: list[int] = []
    cmd_u: list[list[float]] = []
    ts_request: dict[int, float] = {}
    delays: list[float] = []
    while True:
        try:
            msg = conn.recv_match(type=["LOCAL_POSITION_NED", "ATTITUDE_QUATERNION", "HEARTBEAT",
                                        "SET_ACTUATOR_CONTROL_TARGET", "TIMESYNC"])
        except Exception as exc:
            raise UsageError(f"{path}: unreadable tlog ({type(exc).__name__}: {exc})") from None
        if msg is None:
            break
        mtype = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if vehicle is None and mtype in ("LOCAL_POSITION_NED", "ATTITUDE_QUATERNION"):
            vehicle = src
        if mtype == "SET_ACTUATOR_CONTROL_TARGET":
            if src == vehicle or msg.group_mlx != 0:
                continue
            cmd_u.append([float(c) for c in msg.controls[:4]])
            cmd_usec.append(int(msg.time_usec))
            cmd_t.append(math.nan if unanswered is None else unanswered)
            if unanswered is not None:
                last_answered = unanswered
            unanswered = None
        elif mtype == "TIMESYNC":
            if src != vehicle and msg.tc1 == 0 and not math.isnan(last_answered):
                ts_request[int(msg.ts1)] = last_answered
            elif src == vehicle and msg.tc1 != 0 and int(msg.ts1) in ts_request:
                delays.append(msg.tc1 * 1e-9 - ts_request.pop(int(msg.ts1)))
        elif mtype == "HEARTBEAT":
            main_mode = (int(msg.custom_mode) >> 16) & 0xFF
            status[src] = bool(msg.base_mode & _ARMED_FLAG) and main_mode == _OFFBOARD_MAIN
        elif src != vehicle:
            continue
        else:
            tms = int(msg.time_boot_ms)
            if rows and tms <= round(rows[-1][0] * 1e3):
                continue                # late or repeated: older than the last complete sample
            slot = parts.setdefault(tms, {})
            slot["pos" if mtype == "LOCAL_POSITION_NED" else "att"] = msg
            if len(slot) == 2:
                pos, att = slot["pos"], slot["att"]
                t = tms * 1e-3
                rows.append((t, pos.x, pos.y, pos.z, pos.vx, pos.vy, pos.vz,
                             att.q1, att.q2, att.q3, att.q4, status.get(vehicle, False)))
                for k in [k for k in parts if k <= tms]:
                    del parts[k]
                unanswered = t
    if vehicle is None or not rows:
        raise UsageError(f"{path}: no vehicle telemetry (LOCAL_POSITION_NED with ATTITUDE_QUATERNION) "
                         "in this tlog")
    if not cmd_u:
        raise UsageError(f"{path}: no rotor commands (SET_ACTUATOR_CONTROL_TARGET) in this tlog")
    a = np.array(rows, dtype=float)
    return FlightSeries(
        t_s=a[:, 0], position_ned_m=a[:, 1:4], velocity_ned_m_s=a[:, 4:7],
        quaternion_wxyz=a[:, 7:11], controlled=a[:, 11] > 0.5,
        command_t_s=_place_commands(np.array(cmd_t), np.array(cmd_usec, dtype=float)),
        command_controls=np.array(cmd_u, dtype=float),
        link_delay_s=float(np.median(delays)) if delays else None)


def _place_commands(t: np.ndarray, usec: np.ndarray) -> np.ndarray:
    """Vehicle time of each command: its sample's, else its daemon clock less the median offset."""
    paired = ~np.isnan(t)
    if paired.all() or not paired.any():
        return t
    offset = float(np.median(usec[paired] * 1e-6 - t[paired]))
    out = t.copy()
    out[~paired] = usec[~paired] * 1e-6 - offset
    return out
