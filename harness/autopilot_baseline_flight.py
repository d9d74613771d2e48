"""The baseline of issue 29 item 4: a maneuver flown by the autopilot's own position controller.

:func:`fly_px4_baseline` and :func:`fly_ardupilot_baseline` start a fresh SITL, stream the
plan's nominal in time as ``SET_POSITION_TARGET_LOCAL_NED`` (position, velocity, acceleration
feed-forward, yaw and yaw rate; :class:`~mavreg.experiments.autopilot_baseline.BaselineSchedule`)
at 50 Hz, and land the autopilot's way. Parameters and MAVLink only.

- PX4 (SIH): set-points stream (at the vehicle's place on the ground) before OFFBOARD is asked
  for (custom main mode 6), then it arms and takes off under the set-points; after the exit
  hold AUTO.LAND (main 4, sub 6), whose land detector disarms.
- ArduCopter (freestyle frame): GUIDED (mode 4), arm, ``MAV_CMD_NAV_TAKEOFF`` to 1.5 m
  (ArduCopter takes no position target on the ground), then the set-points; after the exit
  hold LAND (mode 9), which disarms on the ground.

Each flight leaves what a mavreg flight leaves, so the same code judges both: ``flight.tlog``
(every message received), ``summary.json`` (``result``, ``reason``, ``events``: the phases in
vehicle time), PX4's ``truth.npz`` and ``.ulg``. The window judged runs from the start of the
maneuver to the end of the exit hold (a vehicle behind its reference at the path's end is still
judged on the rest of the path; samples past the end project outside it and are left out).
PX4 is judged by :func:`~harness.px4_flight.px4_truth` (``HIL_STATE_QUATERNION`` in EKF2's
frame), ArduCopter by :func:`~harness.ardupilot_flight.true_errors_from_tlog` (``SIM_STATE``).
"""
from __future__ import annotations

import json
import struct
import time
from collections import deque
from pathlib import Path

import numpy as np

from mavreg.experiments.autopilot_baseline import (MANEUVER, SETPOINT_RATE_HZ, TYPE_MASK_POS_VEL_ACC_YAW,
                                                   BaselineSchedule)

from .sitl_link import M, SitlError

__all__ = ["fly_px4_baseline", "fly_ardupilot_baseline", "PX4_BASELINE_PARAMS", "ARDUPILOT_BASELINE_PARAMS",
           "PX4_READ_PARAMS", "ARDUPILOT_READ_PARAMS", "VehicleClock", "stream"]

PX4_BASELINE_PARAMS = {"MPC_TILTMAX_AIR": 60.0}
"""What a pilot sets on the default SIH airframe for the comparison: the tilt limit of the
position controller (45 deg by default) raised to 60 deg, under which the slalom's 46 deg (its
thrust against 1 N s/m of drag at 5 m/s; the figure-eight's is 40 deg) is not clipped.
Everything else stays PX4's default (read back into summary.json, :data:`PX4_READ_PARAMS`)."""
PX4_READ_PARAMS = ("MPC_XY_VEL_MAX", "MPC_Z_VEL_MAX_UP", "MPC_Z_VEL_MAX_DN", "MPC_ACC_HOR", "MPC_ACC_HOR_MAX",
                   "MPC_JERK_MAX", "MPC_TILTMAX_AIR", "MPC_THR_MAX", "MPC_THR_XY_MARG", "MPC_THR_HOVER",
                   "MPC_XY_P", "MPC_XY_VEL_P_ACC", "MPC_XY_VEL_I_ACC", "MPC_XY_VEL_D_ACC", "MPC_Z_P",
                   "MPC_Z_VEL_P_ACC", "MC_YAWRATE_MAX", "COM_OF_LOSS_T", "COM_DISARM_LAND")
ARDUPILOT_BASELINE_PARAMS = {"WPNAV_ACCEL": 2000.0, "PSC_JERK_XY": 50.0}
"""What a pilot sets on the freestyle frame for the comparison. GUIDED shapes a
position-velocity-acceleration target towards its own with the waypoint limits: the
acceleration ``WPNAV_ACCEL`` (11 m/s2 in the frame, raised to 20) and the jerk ``PSC_JERK_XY``
(10 m/s3 in the frame, raised to 50: the figure-eight's circles at 4.5 m/s on 3 m turn the
acceleration at 10.1 m/s3). ``WPNAV_SPEED`` (30 m/s) and ``ANGLE_MAX`` (70 deg) already clear
the maneuver."""
ARDUPILOT_READ_PARAMS = ("WPNAV_SPEED", "WPNAV_ACCEL", "WPNAV_ACCEL_Z", "WPNAV_SPEED_UP", "WPNAV_SPEED_DN",
                         "PSC_JERK_XY", "ANGLE_MAX", "PSC_ANGLE_MAX", "PSC_POSXY_P", "PSC_VELXY_P",
                         "PSC_VELXY_I", "PSC_VELXY_D", "GUID_TIMEOUT")
HOLD_S = 3.0
"""Hold at the entry's hold point before the run-in, and at the exit."""
ARDUPILOT_TAKEOFF_M = 1.5
PX4_OFFBOARD = (6, 0)
PX4_AUTO_LAND = (4, 6)
AP_GUIDED, AP_LAND = 4, 9


class VehicleClock:
    """The vehicle's boot time (s) from the host's monotonic clock: the largest offset
    (``time_boot_ms`` less the host time of receipt) seen in the last quarter second, the least
    delayed (short: a simulator under load runs slower than the host's clock)."""

    def __init__(self):
        self._seen: deque = deque()

    def update(self, m) -> None:
        t = getattr(m, "time_boot_ms", None)
        if t is None or m.get_srcComponent() != 1:
            return
        now = time.monotonic()
        self._seen.append((now, t * 1e-3 - now))
        while self._seen and self._seen[0][0] < now - 0.25:
            self._seen.popleft()

    @property
    def ready(self) -> bool:
        return bool(self._seen)

    def vehicle_s(self, host_s: float) -> float:
        return host_s + max(o for _, o in self._seen)


class Tlog:
    """Every message the harness's link receives, written as a ``.tlog`` (pymavlink's own
    ``setup_logfile`` writes nothing on a UDP link): a message hook on the connection."""

    def __init__(self, conn, path: Path):
        self._file = open(path, "wb")
        self._conn = conn
        conn.message_hooks.append(self)

    def __call__(self, conn, msg) -> None:
        if msg.get_type() != "BAD_DATA" and not self._file.closed:
            self._file.write(struct.pack(">Q", int(time.time() * 1e6) & ~3) + msg.get_msgbuf())

    def close(self) -> None:
        if self in self._conn.message_hooks:
            self._conn.message_hooks.remove(self)
        self._file.close()


def _send(link, clock: VehicleClock, sp) -> None:
    p, v, a = sp.position_m, sp.velocity_m_s, sp.accel_m_s2
    t_ms = int(1000 * clock.vehicle_s(time.monotonic())) & 0xFFFFFFFF if clock.ready else 0
    link.conn.mav.set_position_target_local_ned_send(
        t_ms, link.sysid, link.compid, M.MAV_FRAME_LOCAL_NED, TYPE_MASK_POS_VEL_ACC_YAW,
        *(float(c) for c in p), *(float(c) for c in v), *(float(c) for c in a), float(sp.yaw_rad),
        float(sp.yaw_rate_rad_s))


def stream(link, clock: VehicleClock, setpoint_at, until, timeout_s: float, what: str):
    """Send ``setpoint_at(host time)`` (None: nothing) at :data:`SETPOINT_RATE_HZ` and receive in
    between, until ``until(message or None)`` holds; that message. :class:`SitlError` after
    ``timeout_s``. The pace is the stream's; every wait ends on a message or the deadline.
    Between two set-points every waiting message is read (a backlog would stamp the tlog late)."""
    period = 1.0 / SETPOINT_RATE_HZ
    next_send = time.monotonic()
    deadline = next_send + timeout_s
    while True:
        now = time.monotonic()
        if now >= next_send:
            sp = setpoint_at(now)
            if sp is not None:
                _send(link, clock, sp)
            next_send = max(next_send + period, now)
            link._check_alive(what)
        if now > deadline:
            raise link._timeout(what, timeout_s)
        m = link.recv(max(0.001, min(next_send - time.monotonic(), period)))
        while m is not None:
            clock.update(m)
            if until(m):
                return m
            m = link.recv(0.001) if time.monotonic() < next_send else None
        if until(None):
            return None


def _is_heartbeat(m) -> bool:
    return m is not None and m.get_type() == "HEARTBEAT" and m.get_srcComponent() == 1


def _armed(m) -> bool:
    return bool(m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED)


def _read_params(link, names) -> dict:
    out = {}
    for name in names:
        try:
            out[name] = link.get_param(name, timeout_s=2.0)
        except SitlError:
            out[name] = None                  # the firmware has no such parameter
    return out


class _Flight:
    """Bookkeeping of one baseline flight: its events in vehicle time, its outcome."""

    def __init__(self, link, clock: VehicleClock, out: Path):
        self.link, self.clock, self.out = link, clock, out
        self.events: list[dict] = []
        self.result, self.reason = "ok", ""

    def event(self, phase: str, text: str = "", host_s: float | None = None, kind: str = "phase") -> None:
        host_s = time.monotonic() if host_s is None else host_s
        self.events.append({"kind": kind, "phase": phase, "time_s": self.clock.vehicle_s(host_s), "text": text})

    def fly_schedule(self, schedule: BaselineSchedule) -> None:
        """Stream the schedule from now to its end; an event at each phase's start. The schedule
        runs on the vehicle's clock: a simulator slower than real time (a loaded machine) is
        given the reference at the pace its physics runs."""
        t0 = self.clock.vehicle_s(time.monotonic())
        seen: list = []

        def at(now: float):
            t = max(self.clock.vehicle_s(now) - t0, 0.0)
            sp = schedule.at(t)
            if not seen or seen[-1] != sp.phase:
                seen.append(sp.phase)
                judged = sp.phase in (MANEUVER, "hold")
                self.events.append({"kind": "phase" if judged else "schedule", "phase": sp.phase,
                                    "time_s": t0 + schedule.phase_at(t).start_s, "text": ""})
            return sp

        stream(self.link, self.clock, at,
               lambda m: self.clock.vehicle_s(time.monotonic()) - t0 >= schedule.duration_s,
               1.5 * schedule.duration_s + 5.0, "the end of the schedule")
        self.event("land", "the schedule's end: landing")

    def finish(self, extra: dict) -> dict:
        summary = {"result": self.result, "reason": self.reason, "events": self.events, **extra}
        (self.out / "summary.json").write_text(json.dumps(summary, indent=1))
        return summary


def _px4_mode_is(main: int, sub: int):
    return lambda m: _is_heartbeat(m) and (m.custom_mode >> 16) & 0xFF == main and \
        (sub == 0 or (m.custom_mode >> 24) & 0xFF == sub)


def fly_px4_baseline(plan, maneuver: Path, out: Path, vehicle: Path, controller: Path, params: dict | None = None,
                     instance: int | None = None, hold_s: float = HOLD_S, feedforward: str = "kinematic",
                     position_source: str = "gps") -> dict:
    """Fly ``plan`` (planned from ``maneuver`` with ``vehicle`` and ``controller``) through PX4's
    position controller on a fresh SIH; summary.json plus ``px4_truth``. ``feedforward``: the
    maneuver's acceleration (:data:`~mavreg.experiments.autopilot_baseline.FEEDFORWARDS`);
    ``position_source``: EKF2's, ``gps`` or ``mocap`` (:class:`~harness.px4_sitl.Px4Sitl`)."""
    from .px4_flight import px4_truth
    from .px4_sitl import Px4Sitl
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    set_params = {**PX4_BASELINE_PARAMS, **(params or {})}
    with Px4Sitl(params=set_params, instance=instance, position_source=position_source) as px4:
        tlog = Tlog(px4.conn, out / "flight.tlog")
        clock, fl = VehicleClock(), None
        read = _read_params(px4, PX4_READ_PARAMS)
        px4.set_rate(M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50.0)
        px4.set_rate(M.MAVLINK_MSG_ID_ATTITUDE, 10.0)
        att = stream(px4, clock, lambda now: None, lambda m: m is not None and m.get_type() == "ATTITUDE",
                     10.0, "ATTITUDE")
        pos = stream(px4, clock, lambda now: None,
                     lambda m: m is not None and m.get_type() == "LOCAL_POSITION_NED", 10.0, "LOCAL_POSITION_NED")
        ground = np.array([pos.x, pos.y, pos.z])
        fl = _Flight(px4, clock, out)
        schedule = BaselineSchedule(plan, ground, float(att.yaw), hold_s=hold_s, exit_hold_s=hold_s,
                                    feedforward=feedforward)
        idle = lambda now: schedule.at(0.0)                      # noqa: E731  (the ground point)
        t_idle = time.monotonic()
        stream(px4, clock, idle, lambda m: time.monotonic() - t_idle >= 2.5, 5.0, "the idle stream")
        fl.event("preflight", "2.5 s of set-points on the ground: asking for OFFBOARD", kind="schedule")
        _command(px4, clock, idle, M.MAV_CMD_DO_SET_MODE, 1, *PX4_OFFBOARD)
        stream(px4, clock, idle, _px4_mode_is(*PX4_OFFBOARD), 5.0, "OFFBOARD in the HEARTBEAT")
        _command(px4, clock, idle, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        stream(px4, clock, idle, lambda m: _is_heartbeat(m) and _armed(m), 5.0, "armed in the HEARTBEAT")
        fl.event("takeoff", "armed in OFFBOARD: take-off under the set-points")
        fl.fly_schedule(schedule)
        _command(px4, clock, lambda now: schedule.at(schedule.duration_s), M.MAV_CMD_DO_SET_MODE, 1,
                     *PX4_AUTO_LAND)
        stream(px4, clock, lambda now: None, lambda m: _is_heartbeat(m) and not _armed(m), 60.0,
               "the disarm after AUTO.LAND")
        fl.event("disarmed", "PX4 disarmed itself after AUTO.LAND", kind="schedule")
        tlog.close()
        px4.finish(out)
    summary = fl.finish({"autopilot": "px4", "feedforward": feedforward, "params_set": set_params, "params_read": read,
                         "maneuver_window_s": schedule.maneuver_window_s})
    summary["truth"] = px4_truth(out, maneuver, vehicle, controller)
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return summary


def _command(link, clock, setpoint_at, command: int, *params: float) -> None:
    """COMMAND_LONG, streaming set-points while its COMMAND_ACK is awaited; accepted or SitlError."""
    p = [float(v) for v in params] + [0.0] * (7 - len(params))
    link.conn.mav.command_long_send(link.sysid, link.compid, command, 0, *p)
    ack = stream(link, clock, setpoint_at, lambda m: m is not None and m.get_type() == "COMMAND_ACK"
                 and m.command == command, 3.0, f"COMMAND_ACK of {command}")
    if ack.result != M.MAV_RESULT_ACCEPTED:
        texts = "; ".join(t for _, t in link.texts[-3:])
        raise SitlError(f"{link.name}: command {command} {params} refused (result {ack.result}; {texts})")


def fly_ardupilot_baseline(plan, maneuver: Path, out: Path, controller: Path, params: dict | None = None,
                           hold_s: float = HOLD_S, feedforward: str = "kinematic") -> dict:
    """Fly ``plan`` through ArduCopter's GUIDED position controller on a fresh freestyle SITL;
    summary.json plus ``truth`` (SIM_STATE, :func:`true_errors_from_tlog`)."""
    from .ardupilot_flight import true_errors_from_tlog
    from .ardupilot_sitl import ArduPilotSitl
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    set_params = {**ARDUPILOT_BASELINE_PARAMS, **(params or {})}
    with ArduPilotSitl(frame="freestyle", params=set_params) as ap:
        tlog = Tlog(ap.conn, out / "flight.tlog")
        clock = VehicleClock()
        read = _read_params(ap, ARDUPILOT_READ_PARAMS)
        for msg_id, hz in ((M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 100.0), (M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 100.0),
                           (M.MAVLINK_MSG_ID_SIM_STATE, 50.0), (M.MAVLINK_MSG_ID_ATTITUDE, 10.0)):
            ap.set_rate(msg_id, hz)
        ap.command_long(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)
        origin = ap.wait_for(lambda m: m.get_type() == "GPS_GLOBAL_ORIGIN", 10.0, "GPS_GLOBAL_ORIGIN")
        fl = _Flight(ap, clock, out)
        none = lambda now: None                                  # noqa: E731
        stream(ap, clock, none, lambda m: clock.ready, 5.0, "telemetry")
        _command(ap, clock, none, M.MAV_CMD_DO_SET_MODE, 1, AP_GUIDED)
        _command(ap, clock, none, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        fl.event("takeoff", f"armed in GUIDED: NAV_TAKEOFF to {ARDUPILOT_TAKEOFF_M} m")
        _command(ap, clock, none, M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, ARDUPILOT_TAKEOFF_M)
        pos = stream(ap, clock, none, lambda m: m is not None and m.get_type() == "LOCAL_POSITION_NED"
                     and -m.z >= ARDUPILOT_TAKEOFF_M - 0.1 and abs(m.vz) < 0.2, 30.0, "the take-off's altitude")
        att = stream(ap, clock, none, lambda m: m is not None and m.get_type() == "ATTITUDE", 2.0, "ATTITUDE")
        schedule = BaselineSchedule(plan, [pos.x, pos.y, pos.z], float(att.yaw), hold_s=hold_s,
                                    exit_hold_s=hold_s, spool_s=0.0, feedforward=feedforward)
        fl.fly_schedule(schedule)
        _command(ap, clock, lambda now: schedule.at(schedule.duration_s), M.MAV_CMD_DO_SET_MODE, 1, AP_LAND)
        stream(ap, clock, none, lambda m: _is_heartbeat(m) and not _armed(m), 60.0, "the disarm after LAND")
        fl.event("disarmed", "ArduCopter disarmed itself in LAND", kind="schedule")
        tlog.close()
    summary = fl.finish({"autopilot": "ardupilot", "feedforward": feedforward, "params_set": set_params, "params_read": read,
                         "maneuver_window_s": schedule.maneuver_window_s,
                         "origin": {k: getattr(origin, k) for k in ("latitude", "longitude", "altitude")}})
    summary["truth"] = true_errors_from_tlog(out, maneuver, origin, controller)
    if summary["truth"] is not None:
        summary["truth"].update(_ardupilot_estimate(plan, out, origin, _judged_window(summary)))
    (out / "summary.json").write_text(json.dumps(summary, indent=1))
    return summary


def _judged_window(summary: dict) -> tuple[float, float]:
    """(start, end) vehicle time of the judged window: the maneuver's start to the next phase
    (:func:`~mavreg.experiments.via_sitl.maneuver_window`; a baseline flight always has both)."""
    from mavreg.experiments.via_sitl import maneuver_window
    begin, end, _ = maneuver_window(summary["events"])
    if begin is None or end is None:
        raise ValueError("the baseline flight's summary has no complete maneuver window")
    return begin, end


def _ardupilot_estimate(plan, out: Path, origin, window) -> dict:
    """What px4_truth adds for PX4: ``estimate_max_m``, the path error of EKF3's own position
    over the window (the controller's part), and ``ekf_error_max_m``, the largest
    |SIM_STATE - LOCAL_POSITION_NED| in it (the estimate interpolated at each truth sample's
    stamp: the vehicle time of the telemetry before it, 5 ms resolution)."""
    from mavreg.sim.truth import true_errors
    from .ardupilot_flight import _truth_samples
    from .px4_flight import _estimates
    truth = _truth_samples(out / "flight.tlog", origin)
    t_est, est = _estimates(out / "flight.tlog")[:2]
    if truth is None or len(t_est) < 2:
        return {}
    t, pos = truth[0], truth[1]
    sel = (t >= window[0]) & (t <= window[1])
    own = (t_est >= window[0]) & (t_est <= window[1])
    if not sel.any() or not own.any():
        return {}
    at = np.column_stack([np.interp(t[sel], t_est, est[:, k]) for k in range(3)])
    return {"estimate_max_m": true_errors(plan, est[own])["max_m"],
            "ekf_error_max_m": float(np.linalg.norm(pos[sel] - at, axis=1).max())}


def flown_track(out: Path) -> np.ndarray:
    """(N, 3) true NED positions of a baseline flight's judged window (PX4: truth.npz in EKF2's
    origin; ArduCopter: SIM_STATE about the EKF origin), for figures."""
    from types import SimpleNamespace
    out = Path(out)
    summary = json.loads((out / "summary.json").read_text())
    window = _judged_window(summary)
    if summary["autopilot"] == "px4":
        from .px4_flight import _estimates
        truth = np.load(out / "truth.npz")          # stamped by the wall clock, as the tlog
        t, pos = _estimates(out / "flight.tlog")[2](truth["wall_time_s"]), truth["position_ned_m"]
    else:
        from .ardupilot_flight import _truth_samples
        t, pos = _truth_samples(out / "flight.tlog", SimpleNamespace(**summary["origin"]))[:2]
    return pos[(t >= window[0]) & (t <= window[1])]
