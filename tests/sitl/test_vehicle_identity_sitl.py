"""End to end: which vehicle the daemon flies and how it gives up on one it does not.

- Custom firmware that announces MAV_AUTOPILOT_GENERIC, with system id 6, sending first to a
  ``mavreg fly --vehicle udpin:`` port as PX4 SITL does, after a ground station's HEARTBEAT:
  the daemon takes id 6 (never the ground station's), flies the barrel roll with PX4's mode
  layout (and says so), judged on the emulator's ground truth.
- A refusal before take-off (GENERIC in the rates output without ``--dialect``) ends
  ``mavreg fly`` within 2 s of the refusal, exit 1, the cause in one line.
- Pinned to another id, the daemon says within seconds whom it hears and which flag to use.

Every process is stopped by its own id and must be gone at the end.
"""
from __future__ import annotations

import json
import socket
import time

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.daemon.jobs.ctrllog import load_control_log
from mavreg.daemon.jobs.report import ground_truth_errors
from tests.helpers.sitl import BARREL, CONTROLLER, VEHICLE, free_udp_port, load_record, mavreg, start_emulator

pytestmark = pytest.mark.sitl

GCS_HEARTBEAT = mavlink2.MAVLink_heartbeat_message(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID,
                                                   0, 0, mavlink2.MAV_STATE_ACTIVE, 3)


def _line_time(proc, needle: str, timeout_s: float) -> float:
    """The monotonic time at which ``needle`` was first seen in the process's output."""
    proc.wait_line(needle, timeout_s)
    return time.monotonic()


def test_generic_firmware_with_system_id_6_on_udpin_flies_the_barrel_roll(tmp_path, barrel_plan):
    port = free_udp_port()
    out = tmp_path / "out"
    fly = mavreg("fly", str(BARREL), "--vehicle", f"udpin:127.0.0.1:{port}", "--vehicle-lockstep",
                 "--vehicle-params", str(VEHICLE), "--controller", str(CONTROLLER), "--out", str(out),
                 "--timeout-s", "240")
    emu = None
    try:
        fly.wait_line("link: udpin:", 120)
        gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)     # QGroundControl's HEARTBEAT comes first
        gcs.sendto(GCS_HEARTBEAT.pack(mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)),
                   ("127.0.0.1", port))
        gcs.close()
        # the daemon is the only pacer, as for mavreg fly's own lockstep emulator (a period
        # lost to a loaded machine would leave every later command one period late)
        emu, _ = start_emulator(tmp_path / "groundtruth.npz", "--lockstep", "--lockstep-timeout-s", "2",
                                "--world", "ideal",
                                "--vehicle-params", str(VEHICLE), "--autopilot", "generic",
                                "--vehicle-system-id", "6", "--remote", f"udpout:127.0.0.1:{port}")
        code = fly.wait(300)
    finally:
        emu_code = emu.stop() if emu is not None else None
        fly.stop()
    text = "\n".join(fly.lines)
    assert code == 0 and emu_code == 0, text[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    ids = summary["status"]["vehicle_ids"]
    assert ids["system_id"] == 6 and not ids["pinned"] and ids["dropped_by_system"].get("255") == 1
    kinds = {e["kind"]: e["detail"] for e in summary["events"]}
    assert "vehicle system id 6" in kinds["vehicle_id"]
    assert "PX4's mode layout" in kinds["dialect"] and "--dialect px4|ardupilot" in kinds["dialect"]
    ctrl = load_control_log(out / "control.npz")
    ph = [e for e in ctrl["events"] if e["kind"] == "phase"]
    i = next(k for k, e in enumerate(ph) if e["phase"] == "maneuver")
    record = load_record(tmp_path / "groundtruth.npz")
    meta = json.loads(str(record["meta_json"]))
    assert meta["counters"]["lockstep_timeouts"] <= 1, meta["counters"]    # 1: landed, the daemon stops
    assert meta["drops"]["foreign_address"] == 0, meta["drops"]     # our HEARTBEAT came before any command
    truth = ground_truth_errors(record, barrel_plan, ph[i]["time_s"], ph[i + 1]["time_s"])
    print(f"\nGENERIC firmware, system id 6, udpin: true max transverse error {100 * truth['max_m']:.2f} cm "
          f"(loop {100 * truth['segments']['loop']['max_m']:.2f} cm), RMS {100 * truth['rms_m']:.2f} cm")
    assert record["on_ground"][-1] and not record["armed"][-1]
    assert truth["samples"] > 10000 and truth["max_m"] < 0.02 and truth["segments"]["loop"]["max_m"] < 0.02


def test_a_refusal_before_take_off_ends_fly_within_two_seconds(tmp_path):
    out = tmp_path / "out"
    fly = mavreg("fly", str(BARREL), "--lockstep", "--world", "ideal", "--output", "rates",
                 "--emulator-arg=--autopilot=generic", "--controller", str(CONTROLLER), "--out", str(out),
                 "--timeout-s", "120")
    try:
        refused_at = _line_time(fly, "refused: maneuver 'barrel_roll' refused", 120)
        code = fly.wait(30)
        took_s = time.monotonic() - refused_at
    finally:
        fly.stop()
    print(f"\nrefused before take-off: mavreg fly exited {took_s:.2f} s after the refusal")
    assert code == 1 and took_s < 2.0, "\n".join(fly.lines[-20:])
    cause = [ln for ln in fly.lines if ln.startswith("flight failed: gate_autopilot")]
    assert len(cause) == 1 and "--dialect px4|ardupilot" in cause[0]
    assert json.loads((out / "summary.json").read_text())["failure"]["bound"] == "gate_autopilot"


def test_only_another_system_heard_is_said_within_seconds(tmp_path):
    port = free_udp_port()
    fly = mavreg("fly", str(BARREL), "--vehicle", f"udpin:127.0.0.1:{port}", "--vehicle-system-id", "1",
                 "--controller", str(CONTROLLER), "--out", str(tmp_path / "out"), "--timeout-s", "8")
    emu = None
    try:
        fly.wait_line("link: udpin:", 120)
        emu, _ = start_emulator(tmp_path / "groundtruth.npz", "--world", "ideal", "--vehicle-system-id", "6",
                                "--remote", f"udpout:127.0.0.1:{port}")
        started = time.monotonic()
        said_at = _line_time(fly, "nothing from the vehicle's system id 1", 10)
        code = fly.wait(30)
    finally:
        if emu is not None:
            emu.stop()
        fly.stop()
    line = next(ln for ln in fly.lines if "nothing from the vehicle's system id 1" in ln)
    print(f"\nonly system 6 heard: said {said_at - started:.2f} s after the emulator started: {line}")
    assert said_at - started < 4.0 and line.endswith("to fly it, --vehicle-system-id 6")
    assert code == 1
