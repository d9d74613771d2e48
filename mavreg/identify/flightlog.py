"""Read a flight's telemetry and rotor commands for :mod:`mavreg.identify.fit`.

The I/O side of ``mavreg identify``: this module (and only this one in the package) reads
files and uses pymavlink. It turns a ``mavreg fly`` output directory or a bare ``.tlog``
into a :class:`~mavreg.identify.fit.FlightSeries` of plain arrays.

From the ``.tlog`` (every message in and out, in the order the daemon saw or sent it):

- the vehicle is the source of the first LOCAL_POSITION_NED or ATTITUDE_QUATERNION; its
  LOCAL_POSITION_NED and ATTITUDE_QUATERNION of one ``time_boot_ms`` make one sample;
- its HEARTBEATs give armed and the mode, in its autopilot's dialect (PX4 OFFBOARD, ArduCopter
  GUIDED: :mod:`mavreg.daemon.vehicle.autopilots`); each sample carries
  the status of the last HEARTBEAT before it;
- the body rates of a sample are its ATTITUDE_QUATERNION's (rollspeed, pitchspeed,
  yawspeed), or its ATTITUDE's of the same ``time_boot_ms`` where the former are all zero
  (an autopilot that fills only one of them);
- SET_ACTUATOR_CONTROL_TARGET (group 0) from any other source is a rotor command:
  ``controls[0..3]`` times the maximum rotor thrust (the ``rotors`` output); a
  SET_ATTITUDE_TARGET that ignores the attitude and uses the three body rates and the thrust
  (``type_mask`` 128) is a command of the ``rates`` output: body rates (rad/s) and the
  normalized thrust. A flight is of one output or the other. Each command is paired with the
  sample it answered: the daemon answers each complete sample with one command, sent right after
  it, so a command goes with the latest complete sample not answered yet. A command with no
  such sample (real time: sent across a telemetry gap) is placed on the vehicle clock by its
  ``time_usec`` or ``time_boot_ms`` (the daemon's clock) less the median offset of the paired commands;
- the daemon's STATUSTEXTs ``mavreg excitation: start:`` and ``end:`` bound the
  identification flight's rate doublets (:mod:`mavreg.daemon.flight.excitation`), each at the time
  of the last complete sample before it;
- TIMESYNC: the daemon's request (``tc1 = 0``) follows the command of the sample it goes
  with; the vehicle's reply carries its clock (``tc1``, ns). ``tc1`` minus that sample's time
  is the sample-to-actuation delay of the link (:mod:`mavreg.daemon.vehicle.timesync`); the median is
  returned.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..daemon.vehicle.autopilots import dialect_for
from ..errors import UsageError
from .regressors import FlightSeries

__all__ = ["read_flight", "read_tlog"]

_RATES_MASK = 128
"""SET_ATTITUDE_TARGET type_mask bits: attitude ignored (128) ..."""
_RATES_UNUSED = 1 | 2 | 4 | 64
"""... and none of the body rates (1, 2, 4) or the thrust (64) ignored: the rates output."""
_EXCITATION = ("mavreg excitation: start:", "mavreg excitation: end:")
"""The daemon's STATUSTEXTs at the start and the end of the excitation (their first chunk)."""


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


class _Commands:
    """The commands of one output in the order sent: values, daemon clock (us), the time of
    the sample each answered (NaN: none)."""

    def __init__(self):
        self.t: list[float] = []
        self.usec: list[int] = []
        self.u: list[list[float]] = []

    def add(self, values, usec: int, answered: float | None) -> None:
        self.u.append([float(c) for c in values])
        self.usec.append(int(usec))
        self.t.append(math.nan if answered is None else answered)


def _command(msg, cmds: dict) -> tuple | None:
    """(where a daemon's command goes, its values, its clock in us), or None if it is none of
    the two outputs' commands."""
    if msg.get_type() == "SET_ACTUATOR_CONTROL_TARGET":
        if msg.group_mlx != 0:
            return None
        return cmds["rotors"], msg.controls[:4], int(msg.time_usec)
    if not msg.type_mask & _RATES_MASK or msg.type_mask & _RATES_UNUSED:
        return None
    return (cmds["rates"], (msg.body_roll_rate, msg.body_pitch_rate, msg.body_yaw_rate, msg.thrust),
            int(msg.time_boot_ms) * 1000)


def _parse(conn, path: Path) -> FlightSeries:
    vehicle = None                      # (system, component) of the vehicle
    status: dict[tuple, bool] = {}      # source -> armed and in OFFBOARD, its last HEARTBEAT
    parts: dict[int, dict] = {}         # time_boot_ms -> {"att": msg, "pos": msg}
    euler_rates: dict[int, tuple] = {}  # time_boot_ms -> ATTITUDE's body rates
    rows: list[tuple] = []              # (t, p3, v3, q4, controlled, w3)
    unanswered: float | None = None
    last_answered = math.nan
    cmds = {"rotors": _Commands(), "rates": _Commands()}
    ts_request: dict[int, float] = {}
    delays: list[float] = []
    marks: list[list[float]] = []       # [start, end] of each excitation
    while True:
        try:
            msg = conn.recv_match(type=["LOCAL_POSITION_NED", "ATTITUDE_QUATERNION", "ATTITUDE", "HEARTBEAT",
                                        "SET_ACTUATOR_CONTROL_TARGET", "SET_ATTITUDE_TARGET", "TIMESYNC",
                                        "STATUSTEXT"])
        except Exception as exc:
            raise UsageError(f"{path}: unreadable tlog ({type(exc).__name__}: {exc})") from None
        if msg is None:
            break
        mtype = msg.get_type()
        src = (msg.get_srcSystem(), msg.get_srcComponent())
        if vehicle is None and mtype in ("LOCAL_POSITION_NED", "ATTITUDE_QUATERNION"):
            vehicle = src
        if mtype.startswith("SET_"):
            cmd = None if src == vehicle else _command(msg, cmds)
            if cmd is not None:
                cmd[0].add(cmd[1], cmd[2], unanswered)
                if unanswered is not None:
                    last_answered = unanswered
                unanswered = None
        elif mtype == "STATUSTEXT":
            if src != vehicle and rows:
                _excitation_mark(str(msg.text), rows[-1][0], marks)
        elif mtype == "TIMESYNC":
            if src != vehicle and msg.tc1 == 0 and not math.isnan(last_answered):
                ts_request[int(msg.ts1)] = last_answered
            elif src == vehicle and msg.tc1 != 0 and int(msg.ts1) in ts_request:
                delays.append(msg.tc1 * 1e-9 - ts_request.pop(int(msg.ts1)))
        elif mtype == "HEARTBEAT":
            dialect = dialect_for(msg)     # PX4 OFFBOARD or ArduCopter GUIDED; none for a GCS
            info = None if dialect is None else dialect.decode(msg)
            status[src] = info is not None and info.armed and info.offboard
        elif src != vehicle:
            continue
        elif mtype == "ATTITUDE":
            if not rows or int(msg.time_boot_ms) > round(rows[-1][0] * 1e3):
                euler_rates[int(msg.time_boot_ms)] = (msg.rollspeed, msg.pitchspeed, msg.yawspeed)
        else:
            tms = int(msg.time_boot_ms)
            if rows and tms <= round(rows[-1][0] * 1e3):
                continue                # late or repeated: older than the last complete sample
            slot = parts.setdefault(tms, {})
            slot["pos" if mtype == "LOCAL_POSITION_NED" else "att"] = msg
            if len(slot) == 2:
                pos, att = slot["pos"], slot["att"]
                t = tms * 1e-3
                w = (att.rollspeed, att.pitchspeed, att.yawspeed)
                if not any(w):
                    w = euler_rates.get(tms, w)
                rows.append((t, pos.x, pos.y, pos.z, pos.vx, pos.vy, pos.vz,
                             att.q1, att.q2, att.q3, att.q4, status.get(vehicle, False), *w))
                for store in (parts, euler_rates):
                    for k in [k for k in store if k <= tms]:
                        del store[k]
                unanswered = t
    windows = tuple((a, b if math.isfinite(b) else rows[-1][0]) for a, b in marks) if rows else ()
    return _series(path, vehicle, rows, cmds, delays, windows)


def _excitation_mark(text: str, t: float, marks: list) -> None:
    """A start (a new window open to the end) or an end (closing the last) of the excitation."""
    if text.startswith(_EXCITATION[0]):
        marks.append([t, math.inf])
    elif text.startswith(_EXCITATION[1]) and marks and not math.isfinite(marks[-1][1]):
        marks[-1][1] = t


def _series(path: Path, vehicle, rows: list, cmds: dict, delays: list, windows: tuple = ()) -> FlightSeries:
    """The parsed flight as a FlightSeries; UsageError (one line) if it lacks what the fit needs."""
    if vehicle is None or not rows:
        raise UsageError(f"{path}: no vehicle telemetry (LOCAL_POSITION_NED with ATTITUDE_QUATERNION) "
                         "in this tlog")
    n_rot, n_rate = len(cmds["rotors"].u), len(cmds["rates"].u)
    if not n_rot and not n_rate:
        raise UsageError(f"{path}: no rotor commands (SET_ACTUATOR_CONTROL_TARGET) or rate commands "
                         "(SET_ATTITUDE_TARGET, type_mask 128) in this tlog")
    if n_rot and n_rate:
        raise UsageError(f"{path}: both rotor commands ({n_rot}) and rate commands ({n_rate}) in this tlog; "
                         "identify fits a flight of one output")
    output = "rates" if n_rate else "rotors"
    c = cmds[output]
    a = np.array(rows, dtype=float)
    return FlightSeries(
        t_s=a[:, 0], position_ned_m=a[:, 1:4], velocity_ned_m_s=a[:, 4:7],
        quaternion_wxyz=a[:, 7:11], controlled=a[:, 11] > 0.5,
        command_t_s=_place_commands(np.array(c.t), np.array(c.usec, dtype=float)),
        command_controls=np.array(c.u, dtype=float),
        link_delay_s=float(np.median(delays)) if delays else None,
        output=output, body_rates_rad_s=a[:, 12:15], excitation_windows_s=windows)


def _place_commands(t: np.ndarray, usec: np.ndarray) -> np.ndarray:
    """Vehicle time of each command: its sample's, else its daemon clock less the median offset."""
    paired = ~np.isnan(t)
    if paired.all() or not paired.any():
        return t
    offset = float(np.median(usec[paired] * 1e-6 - t[paired]))
    out = t.copy()
    out[~paired] = usec[~paired] * 1e-6 - offset
    return out
