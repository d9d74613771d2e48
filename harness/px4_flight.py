"""``mavreg fly`` on a stock PX4 SITL (SIH), judged by SIH's ground truth.

:func:`fly_on_px4` starts PX4 (:class:`~harness.px4_sitl.Px4Sitl`) with the airframe's
parameters, records SIH's true state (``HIL_STATE_QUATERNION`` at 100 Hz on its display link)
for the whole flight, hands the offboard link to ``mavreg fly --vehicle udpin:...`` and waits
for it. :func:`px4_truth` then measures the flight against the plan in EKF2's frame:

- the truth is converted to NED about EKF2's origin (``GPS_GLOBAL_ORIGIN``), and its height
  moved by the offset between the truth and ``LOCAL_POSITION_NED`` on the ground before
  take-off (EKF2's height follows the barometer: tenths of a metre off the truth);
- SIH stamps its truth with ``time_usec`` 0, so the harness stamps it on arrival by the wall
  clock, as the daemon's tlog stamps the telemetry; the telemetry's ``time_boot_ms`` against
  those stamps maps both onto PX4's boot time, where summary.json's events are;
- the error splits as for the ArduCopter: the estimate's own path error (what mavreg
  regulates on: the controller's part) and the estimate's error, truth less estimate
  (the estimator's part).
"""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

from mavreg.experiments.via_sitl import maneuver_window

from .px4_sitl import Px4Sitl
from .sitl_link import REPO, fly_into_the_maneuver

__all__ = ["fly_on_px4", "px4_truth", "VEHICLE", "AGGRESSIVE_VEHICLE", "CONTROLLER", "AGGRESSIVE_PARAMS"]

VEHICLE = REPO / "mavreg" / "params" / "vehicles" / "px4_sih.yaml"
AGGRESSIVE_VEHICLE = VEHICLE.with_name("px4_sih_aggressive.yaml")
CONTROLLER = REPO / "mavreg" / "params" / "controller" / "px4_sih.yaml"
AGGRESSIVE_PARAMS = {"SIH_T_MAX": 12.5, "SIH_Q_MAX": 0.25, "MC_AIRMODE": 1, "MC_ROLLRATE_MAX": 720.0,
                     "MC_PITCHRATE_MAX": 720.0}
"""SIH's airframe set up for aggressive flight, as a pilot sets up a racing frame: thrust-to-weight
5, roll-pitch airmode (PX4 keeps its roll and pitch torques at low collective) and roll and pitch
rates to 720 deg/s (at the default 220 deg/s a forward loop's pitch rate was clipped at its top).
``mavreg/params/vehicles/px4_sih_aggressive.yaml`` is its vehicle file."""


def fly_on_px4(maneuver: Path, out: Path, vehicle: Path = VEHICLE, controller: Path = CONTROLLER,
               params: dict | None = None, control_rate_hz: float = 200.0, timeout_s: float = 240.0,
               extra_args: tuple = (), instance: int | None = None, position_source: str = "gps") -> dict:
    """Fly ``maneuver`` with mavreg on a fresh PX4; summary.json plus ``px4_truth``
    (:func:`px4_truth`) and ``exit_code``. ``params``: PX4 parameters set before the flight
    (the airframe's ``SIH_*``, an experiment's); ``extra_args``: more ``mavreg fly`` options;
    ``position_source``: EKF2's, ``gps`` or ``mocap`` (:class:`~harness.px4_sitl.Px4Sitl`)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with Px4Sitl(params=params, instance=instance, position_source=position_source) as px4:
        port = px4.release_link()          # the daemon takes the port; PX4 keeps sending there
        cmd = _fly_cmd(port, maneuver, out, vehicle, controller, "--control-rate-hz", f"{control_rate_hz:g}",
                       "--timeout-s", f"{timeout_s:g}", *extra_args)
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s + 60)
        px4.finish(out)
    (out / "fly.log").write_text(proc.stdout + proc.stderr)
    summary = json.loads((out / "summary.json").read_text())
    summary["exit_code"] = proc.returncode
    summary["px4_truth"] = px4_truth(out, maneuver, vehicle, controller)
    (out / "px4_truth.json").write_text(json.dumps(summary["px4_truth"], indent=1))
    return summary


def _estimates(tlog: Path):
    """(PX4's boot time s, NED position) of every LOCAL_POSITION_NED the daemon received, and
    the map from the wall clock to PX4's boot time.

    PX4's SITL clock runs in lockstep with SIH, which falls behind the wall clock on a busy
    machine (1.1 s in 48 s measured), so the map is the telemetry's own: the least of the
    tlog's stamp less ``time_boot_ms`` in each half second (the least delayed frame),
    interpolated."""
    from pymavlink import mavutil
    log = mavutil.mavlink_connection(str(tlog), dialect="common")
    rows = []
    while (m := log.recv_match(type="LOCAL_POSITION_NED")) is not None:
        if m.get_srcComponent() == 1:
            rows.append((m.time_boot_ms * 1e-3, m._timestamp, m.x, m.y, m.z))
    a = np.array(rows, dtype=float).reshape(-1, 5)
    bins = np.floor((a[:, 1] - a[0, 1]) / 0.5) if len(a) else np.zeros(0)
    walls, offsets = [], []
    for b in np.unique(bins):
        sel = bins == b
        k = np.argmin(a[sel, 1] - a[sel, 0])
        walls.append(a[sel, 1][k])
        offsets.append(a[sel, 1][k] - a[sel, 0][k])

    def boot_of_wall(wall_s):
        return np.asarray(wall_s) - np.interp(wall_s, walls, offsets)

    return a[:, 0], a[:, 2:], boot_of_wall


def px4_truth(out: Path, maneuver: Path, vehicle: Path = VEHICLE, controller: Path = CONTROLLER) -> dict | None:
    """True errors of the maneuver's window against its plan in EKF2's frame, the estimate's
    path error and the estimate's own error (None: no maneuver flown or no truth)."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.model.rotation import quats_to_matrices
    from mavreg.planning.plan_io import plan_file
    from mavreg.sim.truth import true_errors
    out = Path(out)
    summary = json.loads((out / "summary.json").read_text())
    truth = np.load(out / "truth.npz")
    t_est, est, boot_of_wall = _estimates(out / "flight.tlog")
    t, pos = boot_of_wall(truth["wall_time_s"]), truth["position_ned_m"].copy()
    if len(t) < 2 or len(t_est) < 2:
        return None
    # the height's offset on the ground, before take-off (the first two seconds of telemetry)
    ground = t_est < t_est[0] + 2.0
    offset = np.median(np.interp(t_est[ground], t, pos[:, 2]) - est[ground, 2])
    pos[:, 2] -= offset
    result = {"ground_height_offset_m": float(offset)}
    begin, end, _ = maneuver_window(summary.get("events") or [])
    if begin is None:
        return result
    window = (begin, math.inf if end is None else end)
    sel = (t >= window[0]) & (t <= window[1])
    plan = plan_file(maneuver, load_vehicle(vehicle), load_controller(controller))
    result.update(true_errors(plan, pos[sel], quats_to_matrices(truth["quaternion_wxyz"][sel]),
                              truth["velocity_ned_m_s"][sel]))
    est_at = np.column_stack([np.interp(t[sel], t_est, est[:, k]) for k in range(3)])
    estimate = true_errors(plan, est_at)
    result["estimate_max_m"] = estimate["max_m"]
    result["estimate_segments"] = {k: v.get("max_m") for k, v in estimate["segments"].items()}
    result["ekf_error_max_m"] = float(np.linalg.norm(pos[sel] - est_at, axis=1).max()) if sel.any() else None
    result["lowest_altitude_m"] = float(-pos[:, 2].max())
    return result


def ulog_texts(ulg: Path) -> list[str]:
    """The texts PX4 wrote into its own flight log (``.ulg``): its own messages and the
    STATUSTEXTs other components of its system sent it (mavreg's phase changes among them)."""
    from pyulog import ULog
    return [m.message for m in ULog(str(ulg), message_name_filter_list=[]).logged_messages]


def truth_touchdowns(out: Path) -> list[tuple[float, float]]:
    """(wall time s, speed m/s) of each ground contact after a lift-off in ``truth.npz``: the
    ground is the truth's height before take-off (within 5 cm)."""
    from mavreg.experiments.robustness_metrics import touchdowns
    truth = np.load(Path(out) / "truth.npz")
    t, pos = truth["wall_time_s"], truth["position_ned_m"]
    on_ground = pos[:, 2] >= pos[0, 2] - 0.05
    return touchdowns(t, truth["velocity_ned_m_s"], on_ground)


def _fly_cmd(port: int, maneuver: Path, out: Path, vehicle: Path, controller: Path, *extra: str) -> list[str]:
    """``mavreg fly`` through body rates on PX4's offboard link (``udpin:`` on ``port``)."""
    return [sys.executable, "-m", "mavreg.cli.main", "fly", str(maneuver), "--vehicle", f"udpin:127.0.0.1:{port}",
            "--output", "rates", "--vehicle-params", str(vehicle), "--controller", str(controller),
            "--out", str(out), *extra]


def _fly_into_the_maneuver(px4: Px4Sitl, maneuver: Path, out: Path, vehicle: Path, controller: Path,
                           after_s: float, wait_s: float = 120.0):
    """``mavreg fly`` on ``px4``'s offboard link (:func:`~harness.sitl_link.fly_into_the_maneuver`,
    its output into ``out/fly.log``)."""
    cmd = _fly_cmd(px4.release_link(), maneuver, out / "flight", vehicle, controller, "--control-rate-hz", "200")
    return fly_into_the_maneuver(cmd, out / "fly.log", after_s, wait_s)


def kill_mid_maneuver(maneuver: Path, out: Path, after_s: float = 2.0, params: dict | None = None,
                      vehicle: Path = VEHICLE, controller: Path = CONTROLLER, wait_s: float = 90.0,
                      position_source: str = "gps") -> dict:
    """Fly ``maneuver`` with mavreg on a fresh PX4, SIGKILL the daemon ``after_s`` (wall clock)
    into the maneuver, then watch PX4 alone: its modes, until it disarms (or ``wait_s``).
    Returns the modes seen after the kill, ``disarmed``, the truth's touchdowns and
    ``killed_at_wall_s``; the truth is kept in ``out/truth.npz``."""
    import os
    import signal
    import time

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    result = {"modes": [], "disarmed": False, "killed_at_wall_s": None}
    with Px4Sitl(params=params, position_source=position_source) as px4:
        proc, flying = _fly_into_the_maneuver(px4, maneuver, out, vehicle, controller, after_s)
        if flying:
            os.kill(proc.pid, signal.SIGKILL)
            result["killed_at_wall_s"] = time.time()
        proc.wait(timeout=10)
        px4.take_link()
        result["modes"], result["disarmed"] = _watch_modes(px4, wait_s)
        px4.finish(out)
    result["touchdowns"] = truth_touchdowns(out)
    (out / "kill.json").write_text(json.dumps(result, indent=1))
    return result


def _watch_modes(px4: Px4Sitl, wait_s: float) -> tuple[list[str], bool]:
    """PX4's modes as its HEARTBEAT changes them, for ``wait_s`` (wall clock) or until it
    disarms; (modes, disarmed)."""
    import time

    from mavreg.daemon.vehicle.autopilots import PX4
    modes, end = [], time.monotonic() + wait_s
    while time.monotonic() < end:
        m = px4.recv(0.5)
        if m is None or m.get_type() != "HEARTBEAT" or m.get_srcComponent() != 1:
            continue
        info = PX4.decode(m)
        if not modes or modes[-1] != info.mode:
            modes.append(info.mode)
        if not info.armed:
            return modes, True
    return modes, False


def kill_and_restart(maneuver: Path, out: Path, after_s: float = 2.0, restart_after_s: float = 5.0,
                     airborne: str = "land", params: dict | None = None, vehicle: Path = VEHICLE,
                     controller: Path = CONTROLLER, timeout_s: float = 180.0) -> dict:
    """Fly ``maneuver`` on a fresh PX4 on motion capture, SIGKILL the daemon ``after_s`` into the
    maneuver, watch PX4's failsafe for ``restart_after_s``, then start ``mavreg fly`` again
    (``--airborne``) and let it end the flight. Returns the second flight's summary with
    ``modes_before_restart``, ``disarmed_before_restart``, ``exit_code`` and the truth's
    ``touchdowns``."""
    import os
    import signal
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with Px4Sitl(params=params, position_source="mocap") as px4:
        proc, flying = _fly_into_the_maneuver(px4, maneuver, out, vehicle, controller, after_s)
        if flying:
            os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
        px4.take_link()
        modes, disarmed = _watch_modes(px4, restart_after_s)
        cmd = _fly_cmd(px4.release_link(), maneuver, out / "again", vehicle, controller, "--control-rate-hz", "200",
                       "--airborne", airborne, "--timeout-s", f"{timeout_s:g}")
        again = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s + 60)
        (out / "again.log").write_text(again.stdout + again.stderr)
        px4.finish(out)
    path = out / "again" / "summary.json"
    summary = json.loads(path.read_text()) if path.exists() else {}
    summary.update(modes_before_restart=modes, disarmed_before_restart=disarmed, killed=flying,
                   exit_code=again.returncode, touchdowns=truth_touchdowns(out))
    (out / "restart.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary


def glitch_mid_maneuver(maneuver: Path, out: Path, offset_m=(0.8, 0.0, 0.0), after_s: float = 2.0,
                        glitch_s: float | None = None, vehicle: Path = VEHICLE, controller: Path = CONTROLLER,
                        timeout_s: float = 240.0) -> dict:
    """Fly ``maneuver`` with mavreg on a fresh PX4 on motion capture and, ``after_s`` into the
    maneuver, shift the motion-capture position fed to EKF2 by ``offset_m`` (NED), for
    ``glitch_s`` seconds or for good: a position source that jumps (a re-referenced or
    mis-tracked motion capture). EKF2 first rejects the jump, then resets its position onto
    it; mavreg sees what EKF2 makes of it. The daemon is left to end the flight. Returns the
    flight's summary (``exit_code``, ``glitch_at_wall_s``) and the truth's ``touchdowns``."""
    import time
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    glitch_at = None
    with Px4Sitl(position_source="mocap") as px4:
        proc, flying = _fly_into_the_maneuver(px4, maneuver, out, vehicle, controller, after_s)
        if flying:
            px4.truth.feed_offset_m = tuple(float(v) for v in offset_m)
            glitch_at = time.time()
            if glitch_s is not None:
                time.sleep(glitch_s)      # the glitch's length, by the wall clock as the feed runs
                px4.truth.feed_offset_m = (0.0, 0.0, 0.0)
        try:
            proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        px4.finish(out)
    summary_path = out / "flight" / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.exists() else {}
    summary.update(exit_code=proc.returncode, glitch_at_wall_s=glitch_at, touchdowns=truth_touchdowns(out))
    (out / "glitch.json").write_text(json.dumps(summary, indent=1, default=str))
    return summary
