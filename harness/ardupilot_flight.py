"""``mavreg fly`` on a stock ArduCopter SITL, judged by the SITL's ground truth.

:func:`fly_on_ardupilot` starts the SITL (:class:`~harness.ardupilot_sitl.ArduPilotSitl`),
sets what a pilot sets once on a real vehicle (``GUID_OPTIONS`` 8, ``GUID_TIMEOUT``; mavreg
itself only checks them), asks for the SITL's true state (``SIM_STATE``) and the EKF origin
(``GPS_GLOBAL_ORIGIN``), then hands the link to ``mavreg fly --vehicle udpin:...`` (the SITL
keeps sending to the same port) and waits for it. The daemon's ``flight.tlog`` keeps every
frame, ``SIM_STATE`` included: :func:`true_errors_from_tlog` turns those into NED positions
about the EKF origin, stamps each with the vehicle time of the telemetry before it, and
measures them against the plan over the maneuver's window (summary.json's events).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from .ardupilot_mocap import HOME, ned_m
from .ardupilot_sitl import M, ArduPilotSitl
from .sitl_link import REPO, fly_into_the_maneuver

__all__ = ["fly_on_ardupilot", "kill_and_restart_on_ardupilot", "sim_touchdowns", "true_errors_from_tlog", "vehicle_args", "PILOT_PARAMS", "VEHICLE", "CONTROLLER", "CONTROLLERS"]

VEHICLE = REPO / "mavreg" / "params" / "vehicles" / "ardupilot_freestyle.yaml"
CONTROLLER = REPO / "mavreg" / "params" / "controller" / "freestyle.yaml"
CONTROLLERS = {"gps": CONTROLLER, "vicon": CONTROLLER, "mocap": CONTROLLER.with_name("freestyle_mocap.yaml")}
"""The controller file each position source flies with by default: the motion-capture feed's
estimate is good enough for a 20 times stiffer position loop (docs/autopilots.md)."""
PILOT_PARAMS = {"GUID_OPTIONS": 8, "GUID_TIMEOUT": 0.5, "ATC_ANGLE_BOOST": 0}
"""What docs/autopilots.md tells a pilot to set before flying mavreg."""


def fly_on_ardupilot(maneuver: Path, out: Path, control_rate_hz: float = 200.0, timeout_s: float = 240.0,
                     extra_args: tuple = (), frame: str = "freestyle", params: dict | None = None,
                     position_source: str = "gps", controller: Path | None = None) -> dict:
    """Fly ``maneuver`` with mavreg on a fresh SITL; summary.json plus ``ardupilot_truth``.
    ``params``: parameters set before the flight on top of :data:`PILOT_PARAMS` (an experiment's);
    ``position_source``: the EKF's, ``gps``, ``vicon`` or ``mocap`` (:class:`ArduPilotSitl`);
    ``controller``: the controller file, :data:`CONTROLLERS` of the position source by default."""
    out = Path(out)
    controller = Path(controller) if controller is not None else CONTROLLERS[position_source]
    with ArduPilotSitl(frame=frame, params={**PILOT_PARAMS, **(params or {})},
                       position_source=position_source) as sitl:
        sitl.set_rate(M.MAVLINK_MSG_ID_SIM_STATE, 50.0)
        sitl.command_long(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_GPS_GLOBAL_ORIGIN)
        origin = sitl.wait_for(lambda m: m.get_type() == "GPS_GLOBAL_ORIGIN", 10.0, "GPS_GLOBAL_ORIGIN")
        if position_source != "gps":          # the EKF's local frame is the vision frame, about HOME
            origin = SimpleNamespace(latitude=round(HOME[0] * 1e7), longitude=round(HOME[1] * 1e7),
                                     altitude=round(HOME[2] * 1e3))
        port = sitl.release_link()        # the daemon takes the port; the SITL keeps sending there
        cmd = _fly_cmd(port, maneuver, out, controller, "--control-rate-hz", f"{control_rate_hz:g}",
                       "--timeout-s", f"{timeout_s:g}", *extra_args)
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s + 60)
    out.mkdir(parents=True, exist_ok=True)
    (out / "fly.log").write_text(proc.stdout + proc.stderr)
    (out / "truth_origin.json").write_text(json.dumps(     # the local frame's origin (decompose)
        {k: getattr(origin, k) for k in ("latitude", "longitude", "altitude")}))
    summary = json.loads((out / "summary.json").read_text())
    summary["exit_code"] = proc.returncode
    summary["ardupilot_truth"] = true_errors_from_tlog(out, maneuver, origin, controller)
    return summary


def _fly_cmd(port: int, maneuver: Path, out: Path, controller: Path, *extra: str) -> list[str]:
    """``mavreg fly`` on the SITL's link (``udpin:`` on ``port``) with the freestyle vehicle file."""
    return [sys.executable, "-m", "mavreg.cli.main", "fly", str(maneuver), *vehicle_args(port, controller),
            "--out", str(out), *extra]


def vehicle_args(port: int, controller: Path = CONTROLLER) -> list[str]:
    """The SITL's link (``udpin:`` on ``port``) and the freestyle vehicle and controller files, as
    ``mavreg fly`` and ``mavreg serve`` take them."""
    return ["--vehicle", f"udpin:127.0.0.1:{port}", "--vehicle-params", str(VEHICLE), "--controller", str(controller)]


def kill_and_restart_on_ardupilot(maneuver: Path, out: Path, after_s: float = 2.0, restart_after_s: float = 3.0,
                                  airborne: str = "land", timeout_s: float = 180.0) -> dict:
    """Fly ``maneuver`` on a fresh SITL (GPS), SIGKILL the daemon ``after_s`` (wall clock) into the
    maneuver, leave ArduCopter alone for ``restart_after_s`` (its GUIDED timeout holds it level,
    its climb rate at zero), then start ``mavreg fly --airborne`` again on the same link and let
    it end the flight. Returns the second flight's summary with ``killed``, ``exit_code`` and the
    truth's touchdowns (``SIM_STATE`` in both daemons' tlogs: (wall s, down speed m/s))."""
    import os
    import signal
    import time
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with ArduPilotSitl(frame="freestyle", params=dict(PILOT_PARAMS)) as sitl:
        sitl.set_rate(M.MAVLINK_MSG_ID_SIM_STATE, 50.0)
        port = sitl.release_link()
        first, killed = fly_into_the_maneuver(_fly_cmd(port, maneuver, out / "flight", CONTROLLER),
                                              out / "fly.log", after_s, wait_s=240.0)
        if killed:
            os.kill(first.pid, signal.SIGKILL)
        first.wait(timeout=10)
        time.sleep(restart_after_s)          # the vehicle alone, its failsafe in charge
        again = subprocess.run(_fly_cmd(port, maneuver, out / "again", CONTROLLER, "--airborne", airborne,
                                        "--timeout-s", f"{timeout_s:g}"),
                               capture_output=True, text=True, timeout=timeout_s + 60)
    (out / "again.log").write_text(again.stdout + again.stderr)
    path = out / "again" / "summary.json"
    summary = json.loads(path.read_text()) if path.exists() else {}
    downs = _sim_touchdowns([out / "flight" / "flight.tlog", out / "again" / "flight.tlog"])
    summary.update(killed=killed, exit_code=again.returncode, touchdowns=downs)
    (out / "restart.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary


def _sim_touchdowns(tlogs: list[Path]) -> list[tuple[float, float]]:
    """(tlog time s, speed m/s) of each ground contact after a lift-off in the SITL's truth
    (``SIM_STATE`` in the daemons' tlogs, in order): :func:`sim_touchdowns`."""
    from pymavlink import mavutil
    rows = []
    for tlog in tlogs:
        log = mavutil.mavlink_connection(str(tlog)) if Path(tlog).exists() else None
        while log is not None and (m := log.recv_match(type="SIM_STATE")) is not None:
            rows.append((m._timestamp, m.alt, m.vn, m.ve, m.vd))
    return sim_touchdowns(rows)


def sim_touchdowns(rows) -> list[tuple[float, float]]:
    """(time s, speed m/s) of each ground contact after a lift-off in SIM_STATE rows (time s,
    altitude m, vn, ve, vd m/s), in order: the ground is the first row's altitude (within 5 cm)."""
    from mavreg.experiments.robustness_metrics import touchdowns
    if not len(rows):
        return []
    a = np.array(rows, dtype=float)
    on_ground = a[:, 1] <= a[0, 1] + 0.05
    return touchdowns(a[:, 0], a[:, 2:5], on_ground)


def _ned(lat_deg, lon_deg, alt_m, origin) -> np.ndarray:
    """NED (m) about a GPS_GLOBAL_ORIGIN-like ``origin`` (1e-7 deg, mm)."""
    return np.array(ned_m(lat_deg, lon_deg, alt_m,
                          (origin.latitude * 1e-7, origin.longitude * 1e-7, origin.altitude * 1e-3)))


def _truth_samples(tlog: Path, origin):
    """(vehicle time s, NED position, rotation, NED velocity) of every SIM_STATE in the tlog."""
    from pymavlink import mavutil

    from mavreg.model.rotation import quats_to_matrices
    log = mavutil.mavlink_connection(str(tlog), dialect="common")
    t_vehicle, rows = math.nan, []
    while (m := log.recv_match()) is not None:
        kind = m.get_type()
        if kind in ("ATTITUDE_QUATERNION", "LOCAL_POSITION_NED") and m.get_srcComponent() == 1:
            t_vehicle = m.time_boot_ms / 1000.0
        elif kind == "SIM_STATE" and math.isfinite(t_vehicle):
            lat = m.lat_int * 1e-7 if getattr(m, "lat_int", 0) else m.lat
            lon = m.lon_int * 1e-7 if getattr(m, "lon_int", 0) else m.lon
            rows.append((t_vehicle, _ned(lat, lon, m.alt, origin), (m.q1, m.q2, m.q3, m.q4), (m.vn, m.ve, m.vd)))
    if not rows:
        return None
    t = np.array([r[0] for r in rows])
    return t, np.array([r[1] for r in rows]), quats_to_matrices(np.array([r[2] for r in rows])), \
        np.array([r[3] for r in rows])


def true_errors_from_tlog(out: Path, maneuver: Path, origin, controller: Path = CONTROLLER) -> dict | None:
    """True errors of the maneuver's window against its plan (None: no maneuver, no truth)."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.experiments.via_sitl import maneuver_window
    from mavreg.planning.plan_io import plan_file
    from mavreg.sim.truth import true_errors
    summary = json.loads((Path(out) / "summary.json").read_text())
    begin, end, _ = maneuver_window(summary.get("events") or [])
    if begin is None:
        return None
    truth = _truth_samples(Path(out) / "flight.tlog", origin)
    if truth is None:
        return None
    t, pos, rot, vel = truth
    end = t[-1] if end is None else end
    sel = (t >= begin) & (t <= end)
    plan = plan_file(maneuver, load_vehicle(VEHICLE), load_controller(controller))
    result = true_errors(plan, pos[sel], rot[sel], vel[sel])
    result["lowest_altitude_m"] = float((-pos[:, 2]).min()) if len(pos) else math.nan
    return result
