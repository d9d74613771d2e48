"""Flights through firmware_sim's link faults (``--link-faults``, in vehicle time), for the
end-to-end link-fault tests and docs/reliability.md's figures.

Both processes as the user runs them: ``python -m firmware_sim --lockstep`` (default world:
realistic) and ``mavreg fly --vehicle-lockstep`` (default controller: realistic.yaml)."""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER

from tests.helpers.sitl import BARREL, load_record, mavreg, start_emulator

NEAR = Path(__file__).resolve().parent / "barrel_roll_near.yaml"
REAL_CONTROLLER = REAL_CONTROLLER
GROUND_Z_M = 0.05


def fly_faulted(tmp: Path, faults: str | None, maneuver: Path = BARREL, duration_s: float | None = None,
                stall_factor: float | None = None) -> dict:
    """One flight; ``faults`` as ``--link-faults`` takes it (``None``: the clean run, same seed).

    ``duration_s``: the emulator stops at this vehicle time (the flight is cut there);
    ``stall_factor`` 0: once the daemon stops streaming, the emulator runs on as fast as it
    can (the vehicle's failsafe flies) until ``duration_s``."""
    record = tmp / "groundtruth.npz"
    args = ["--lockstep", "--lockstep-timeout-s", "3"]
    if faults:
        args += ["--link-faults", faults]
    if duration_s is not None:
        args += ["--duration-s", f"{duration_s:g}"]
    if stall_factor is not None:
        args += ["--lockstep-stall-factor", f"{stall_factor:g}"]
    t0 = time.monotonic()
    emu, url = start_emulator(record, *args)
    out = tmp / "out"
    try:
        fly = mavreg("fly", str(maneuver), "--vehicle", url, "--vehicle-lockstep", "--out", str(out),
                     "--controller", str(REAL_CONTROLLER), "--timeout-s", "200")
        code = fly.wait(260)
        emu_code = emu.wait(120) if duration_s is not None else None
    finally:
        fly.stop()
        emu_code = emu.stop() if emu_code is None else emu_code
    summary = json.loads((out / "summary.json").read_text())
    return {"code": code, "emu_code": emu_code, "summary": summary, "record": load_record(record),
            "lines": fly.lines, "emu_lines": emu.lines, "wall_s": time.monotonic() - t0}


def events(f: dict, kind: str | None = None) -> list:
    return [e for e in f["summary"]["events"] if kind is None or e["kind"] == kind]


def maneuver_window(f: dict) -> tuple[float, float | None]:
    """Vehicle times of the maneuver's start and of the phase after it (None: not left)."""
    phases = events(f, "phase")
    t0 = next(e["time_s"] for e in phases if e["phase"] == "maneuver")
    after = [e["time_s"] for e in phases if e["time_s"] > t0]
    return t0, (after[0] if after else None)


_PLANS: dict = {}


def true_errors(f: dict, maneuver: Path) -> dict:
    """Ground-truth errors (:func:`mavreg.daemon.jobs.report.ground_truth_errors`) from the maneuver's
    start to the phase after it (or the recording's end), against the plan the daemon flew."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.daemon.jobs.report import ground_truth_errors
    from mavreg.planning.plan_io import plan_file
    if maneuver not in _PLANS:
        _PLANS[maneuver] = plan_file(maneuver, load_vehicle(DEFAULT_VEHICLE),
                                     load_controller(REAL_CONTROLLER))
    t0, t1 = maneuver_window(f)
    rec = f["record"]
    return ground_truth_errors(rec, _PLANS[maneuver], t0, rec["t_s"][-1] if t1 is None else t1)


def safe_end(f: dict) -> dict:
    """What the recording says of the end: on the ground, disarmed, no motor stopped in the air."""
    rec = f["record"]
    armed = rec["armed"].astype(bool)
    alt = -rec["position_ned_m"][:, 2]
    # a disarm (motors off) while more than GROUND_Z_M up would be a stop in the air
    disarm = np.flatnonzero(armed[:-1] & ~armed[1:]) + 1
    return {"on_ground": bool(rec["on_ground"][-1]), "armed": bool(armed[-1]),
            "disarmed_in_air": int(sum(alt[i] > GROUND_Z_M for i in disarm)),
            "max_speed_m_s": float(np.linalg.norm(rec["velocity_ned_m_s"], axis=1).max())}


def fly_through_proxy(tmp: Path, faults: str, maneuver: Path = NEAR) -> dict:
    """A real-time flight through the UDP proxy (``python -m mavreg.tools.faultlink``, wall
    clock): firmware_sim in real time <- proxy <- ``mavreg fly``; the proxy's counters too."""
    import sys
    from tests.helpers.sitl import Proc
    record = tmp / "groundtruth.npz"
    t0 = time.monotonic()
    emu, url = start_emulator(record)
    proxy = fly = None
    out = tmp / "out"
    try:
        port = url.rsplit(":", 1)[1]
        proxy = Proc([sys.executable, "-m", "mavreg.tools.faultlink", "--listen", "127.0.0.1:0",
                      "--vehicle", f"127.0.0.1:{port}", "--both", faults, "--seed", "0"])
        line = proxy.wait_line("faultlink listening on", 30)
        listen = line.split()[3]
        fly = mavreg("fly", str(maneuver), "--vehicle", f"udpout:{listen}", "--out", str(out),
                     "--controller", str(REAL_CONTROLLER), "--timeout-s", "200")
        code = fly.wait(260)
    finally:
        if fly is not None:
            fly.stop()
        if proxy is not None:
            proxy.stop()
        emu_code = emu.stop()
    summary = json.loads((out / "summary.json").read_text())
    return {"code": code, "emu_code": emu_code, "summary": summary, "record": load_record(record),
            "lines": fly.lines, "proxy_lines": proxy.lines, "wall_s": time.monotonic() - t0}
