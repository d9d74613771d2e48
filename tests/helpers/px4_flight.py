"""``mavreg fly`` on a stock PX4 SITL (SIH), judged by SIH's ground truth.

:func:`fly_on_px4` starts PX4 (:class:`~tests.helpers.px4_sitl.Px4Sitl`) with the airframe's
parameters, records SIH's true state (``HIL_STATE_QUATERNION`` at 100 Hz on its display link)
for the whole flight, hands the offboard link to ``mavreg fly --vehicle udpin:...`` and waits
for it. :func:`px4_truth` then measures the flight against the plan in EKF2's frame:

- the truth is converted to NED about EKF2's origin (``GPS_GLOBAL_ORIGIN``), and its height
  moved by the offset between the truth and ``LOCAL_POSITION_NED`` on the ground before
  take-off (EKF2's height follows the barometer: tenths of a metre off the truth);
- both are stamped with PX4's boot time (``time_usec``, ``time_boot_ms``), so the maneuver's
  window comes from summary.json's events;
- the error splits as for the ArduCopter: the estimate's own path error (what mavreg
  regulates on: the controller's part) and the estimate's error, truth less estimate
  (the estimator's part).
"""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from .px4_sitl import Px4Sitl

__all__ = ["fly_on_px4", "px4_truth", "VEHICLE", "CONTROLLER", "AGGRESSIVE_PARAMS"]

REPO = Path(__file__).resolve().parents[2]
VEHICLE = REPO / "mavreg" / "params" / "vehicles" / "px4_sih.yaml"
CONTROLLER = REPO / "mavreg" / "params" / "controller" / "px4_sih.yaml"
AGGRESSIVE_PARAMS = {"SIH_T_MAX": 12.5, "SIH_Q_MAX": 0.25}
"""SIH's airframe set up for aggressive flight (thrust-to-weight 5): a racing frame's motors."""


def fly_on_px4(maneuver: Path, out: Path, vehicle: Path = VEHICLE, controller: Path = CONTROLLER,
               params: dict | None = None, control_rate_hz: float = 200.0, timeout_s: float = 240.0,
               extra_args: tuple = (), instance: int | None = None) -> dict:
    """Fly ``maneuver`` with mavreg on a fresh PX4; summary.json plus ``px4_truth``
    (:func:`px4_truth`) and ``exit_code``. ``params``: PX4 parameters set before the flight
    (the airframe's ``SIH_*``, an experiment's); ``extra_args``: more ``mavreg fly`` options."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with Px4Sitl(params=params, instance=instance) as px4:
        port = px4.release_link()          # the daemon takes the port; PX4 keeps sending there
        cmd = [sys.executable, "-m", "mavreg.cli.main", "fly", str(maneuver), "--vehicle", f"udpin:127.0.0.1:{port}",
               "--output", "rates", "--vehicle-params", str(vehicle), "--controller", str(controller),
               "--control-rate-hz", f"{control_rate_hz:g}", "--out", str(out), "--timeout-s", f"{timeout_s:g}",
               *extra_args]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s + 60)
        px4.stop()
        px4.truth.save(out / "truth.npz", px4.origin)
        for ulg in px4.ulogs():             # PX4's own log of the flight
            shutil.copy(ulg, out / ulg.name)
        px4.cleanup()
    (out / "fly.log").write_text(proc.stdout + proc.stderr)
    summary = json.loads((out / "summary.json").read_text())
    summary["exit_code"] = proc.returncode
    summary["px4_truth"] = px4_truth(out, maneuver, vehicle, controller)
    (out / "px4_truth.json").write_text(json.dumps(summary["px4_truth"], indent=1))
    return summary


def _estimates(tlog: Path):
    """(time s, NED position) of every LOCAL_POSITION_NED the daemon received."""
    from pymavlink import mavutil
    log = mavutil.mavlink_connection(str(tlog), dialect="common")
    rows = []
    while (m := log.recv_match(type="LOCAL_POSITION_NED")) is not None:
        if m.get_srcComponent() == 1:
            rows.append((m.time_boot_ms * 1e-3, m.x, m.y, m.z))
    a = np.array(rows, dtype=float).reshape(-1, 4)
    return a[:, 0], a[:, 1:]


def _window(summary: dict) -> tuple[float, float] | None:
    """The maneuver's (begin, end) in vehicle time from summary.json's events, or None."""
    events = [e for e in summary.get("events") or [] if e.get("kind") == "phase" and e.get("time_s") is not None]
    begin = [e["time_s"] for e in events if e.get("phase") == "maneuver"]
    if not begin:
        return None
    after = [e["time_s"] for e in events if e["time_s"] > begin[0] and e.get("phase") != "maneuver"]
    return begin[0], (after[0] if after else math.inf)


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
    t, pos = truth["time_s"], truth["position_ned_m"].copy()
    t_est, est = _estimates(out / "flight.tlog")
    if len(t) < 2 or len(t_est) < 2:
        return None
    # the height's offset on the ground, before take-off (the first two seconds of telemetry)
    ground = t_est < t_est[0] + 2.0
    offset = np.median(np.interp(t_est[ground], t, pos[:, 2]) - est[ground, 2])
    pos[:, 2] -= offset
    result = {"ground_height_offset_m": float(offset)}
    window = _window(summary)
    if window is None:
        return result
    sel = (t >= window[0]) & (t <= window[1])
    plan = plan_file(maneuver, load_vehicle(vehicle), load_controller(controller))
    result.update(true_errors(plan, pos[sel], quats_to_matrices(truth["quaternion_wxyz"][sel]),
                              truth["velocity_ned_m_s"][sel]))
    est_at = np.column_stack([np.interp(t[sel], t_est, est[:, k]) for k in range(3)])
    estimate = true_errors(plan, est_at)
    result["estimate_max_m"] = estimate["max_m"]
    result["estimate_segments"] = {k: v.get("max_m") for k, v in estimate["segments"].items()}
    result["ekf_error_max_m"] = float(np.linalg.norm(pos[sel] - est_at, axis=1).max()) if sel.any() else None
    result["lowest_altitude_m"] = float(-pos[:, 2].min() - 0.0)
    return result
