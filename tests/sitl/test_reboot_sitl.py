"""The vehicle reboots, end to end (issue 32 item 2): ``mavreg serve`` and the bundled
emulator in lockstep, judged on the emulator's recording (its truth).

- Between flights: a hop flies and lands; a ground station (system 245, a configured peer of
  the emulator) reboots the vehicle with MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN; the daemon sees
  the clock go back, rebuilds, and the next upload flies, in the same ``serve``.
- In the air: ``--reboot-at-s`` takes the autopilot down in the hop's hold; the flight ends
  as a loss with the reboot named, the daemon sends no motor stop and does not crash, and
  it flies the next upload once the rebooted vehicle is back.
"""
from __future__ import annotations

import json
import signal
import socket
import time

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as M

from mavreg.daemon.jobs.endpoint import request
from tests.helpers.sitl import load_record, mavreg, start_emulator
from tests.helpers.repo import ROOT as REPO

pytestmark = [pytest.mark.sitl, pytest.mark.slow]     # 2-3 min: two hops, planning, a reboot

HOP = (REPO / "tests/sitl/gcs_hop.yaml").read_text()
GCS = 245
EMULATOR = ("--lockstep", "--world", "ideal", "--lockstep-timeout-s", "30", "--peer-system-id", str(GCS))
SERVE = ("--vehicle-lockstep", "--stale-timeout-s", "30")


def _hop(serve, sock, name: str, number: int) -> str:
    """Upload the hop, land after it (serve holds for the next upload otherwise): its line."""
    assert request(sock, {"op": "upload", "name": name, "yaml": HOP}, 600)["ok"]
    serve.wait_line("maneuver finished", 900, nth=number)
    assert request(sock, {"op": "land"}, 60)["ok"]
    return serve.wait_line(f"flight {number}:", 300, nth=1 if number == 1 else 2)   # after "waiting"


def _touchdowns(rec: dict) -> list[tuple[float, float]]:
    """(time s, descent m/s) of every touchdown of the truth: the vertical speed just before
    (ground contacts at no speed, the spool-down's millimetre hops, are not touchdowns)."""
    g = rec["on_ground"].astype(int)
    idx = np.flatnonzero(np.diff(g) == 1) + 1
    downs = [(float(rec["t_s"][i]), float(rec["velocity_ned_m_s"][i - 1, 2])) for i in idx]
    return [(t, v) for t, v in downs if v > 0.01]


def _ground_station_reboot(port: int, timeout_s: float = 60.0) -> int:
    """Say HEARTBEAT as system 245 and ask for a reboot; the COMMAND_ACK's result."""
    mav = M.MAVLink(None, srcSystem=GCS, srcComponent=190)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.connect(("127.0.0.1", port))
        s.settimeout(0.5)
        s.send(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(mav))
        s.send(M.MAVLink_command_long_message(1, 1, M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 0,
                                              1, 0, 0, 0, 0, 0, 0).pack(mav))
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                data = s.recv(65535)
            except socket.timeout:
                continue
            for m in mav.parse_buffer(data) or []:
                if m.get_type() == "COMMAND_ACK" and m.command == M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
                    return m.result
    raise AssertionError("no COMMAND_ACK to the reboot")


def _serve(url: str, sock) -> object:
    serve = mavreg("serve", "--vehicle", url, *SERVE, "--socket", str(sock))
    serve.wait_line("control endpoint", 120)
    return serve


def test_a_reboot_between_flights_is_survived_and_the_next_upload_flies(tmp_path):
    rec_path, sock = tmp_path / "truth.npz", tmp_path / "d.sock"
    emu, url = start_emulator(rec_path, *EMULATOR)
    serve = None
    try:
        serve = _serve(url, sock)
        first = _hop(serve, sock, "first", 1)
        serve.wait_line("flight 2: waiting for an upload", 30)
        assert _ground_station_reboot(int(url.rsplit(":", 1)[1])) == M.MAV_RESULT_ACCEPTED
        seen = serve.wait_line("vehicle_rebooted", 60)
        second = _hop(serve, sock, "second", 2)
        status = request(sock, {"op": "status"}, 60)["status"]
        code = serve.stop(signal.SIGINT, 60)
    finally:
        if serve is not None:
            serve.stop()
        emu.stop()
    print(f"\n{first}\n{seen}\n{second}")
    assert code == 0, serve.lines[-20:]
    assert first.startswith("flight 1: ok") and second.startswith("flight 2: ok"), (first, second)
    assert "went back from" in seen and "on the ground" in seen
    assert status["flights"]["ok"] == 2 if "ok" in status["flights"] else True
    rec = load_record(rec_path)
    meta = json.loads(str(rec["meta_json"]))
    (reboot,) = meta["reboots"]
    assert reboot["on_ground"] and not reboot["armed"] and reboot["why"].startswith("by command")
    t, armed = rec["t_s"], rec["armed"]
    assert not armed[(t >= reboot["down_t_s"]) & (t <= reboot["up_t_s"])].any()
    assert armed[t > reboot["up_t_s"]].any()                    # armed again after the reboot: flew
    downs = _touchdowns(rec)
    print(f"touchdowns (t s, descent m/s): {downs}; reboot {reboot}")
    assert len(downs) == 2 and all(v < 1.0 for _, v in downs)
    assert downs[0][0] < reboot["down_t_s"] < reboot["up_t_s"] < downs[1][0]
    assert meta["reboot_impacts"] == []


REBOOT_AT_S = 10.0
"""Sim time of the injected reboot: in the hop's maneuver, 1.5 m up (``fly`` plans before it
talks to the vehicle, and a lockstep emulator is frozen until then: the timing is the flight's)."""


def test_a_reboot_in_the_air_ends_as_a_loss_with_no_motor_stop_from_mavreg(tmp_path):
    rec_path, hop = tmp_path / "truth.npz", tmp_path / "hop.yaml"
    hop.write_text(HOP)
    emu, url = start_emulator(rec_path, *EMULATOR, "--reboot-at-s", str(REBOOT_AT_S))
    try:
        fly = mavreg("fly", str(hop), "--vehicle", url, *SERVE, "--out", str(tmp_path / "out"))
        code = fly.wait(900)
        emu_code = emu.stop()
    finally:
        emu.stop()
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    failure = summary["failure"]
    print("\n" + "\n".join(ln for ln in fly.lines if "rebooted" in ln or "hand_over" in ln or "failed" in ln))
    assert code == 1 and emu_code == 0, fly.lines[-20:]
    assert failure["bound"] in ("vehicle_rebooted", "vehicle_mode", "link_lost"), failure
    assert "rebooted" in failure["detail"] + failure["action"], failure
    assert "motors stopped" not in failure["action"] and "Traceback" not in "\n".join(fly.lines)
    rec = load_record(rec_path)
    meta = json.loads(str(rec["meta_json"]))
    (reboot,) = meta["reboots"]
    assert reboot["armed"] and not reboot["on_ground"] and reboot["down_t_s"] == pytest.approx(REBOOT_AT_S)
    t, armed = rec["t_s"], rec["armed"]
    first_armed = t[np.argmax(armed)]
    assert armed[(t >= first_armed) & (t < reboot["down_t_s"])].all()      # nobody disarmed it before
    assert not armed[t > reboot["down_t_s"]].any()                          # never armed again
    (impact,) = meta["reboot_impacts"]
    print(f"reboot {reboot}; the fall's impact {impact}")
    assert impact["speed_m_s"] > 3.0                    # the fall's, recorded: no crash exit
