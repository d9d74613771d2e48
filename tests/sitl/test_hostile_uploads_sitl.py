"""End-to-end: a daemon flying the barrel roll on firmware_sim --lockstep receives hostile
uploads (malformed JSON, 5 MB, a YAML alias bomb, another user) and flies on: each gets a
one-line refusal or rejection, the flight lands ok, and its control loop is never stalled
(issue 21: inputs that cannot hurt)."""
from __future__ import annotations

import json
import signal
import socket
import threading

import pytest

from pathlib import Path

from sitl_helpers import CONTROLLER, VEHICLE_IDEAL, mavreg, start_emulator
from mavreg.daemon.endpoint import request

HOP = Path(__file__).with_name("hostile_hop.yaml")
"""A 6 m line at 2 m/s: the flight is not the subject here, and a short one keeps the test short."""

pytestmark = pytest.mark.sitl


def alias_bomb(levels: int) -> str:
    """'Billion laughs' in the ``kind:`` value: 10^levels strings from a few hundred bytes."""
    lines = ["a0: &a0 [" + ", ".join(['"lol"'] * 10) + "]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, levels)]
    return "\n".join(lines + [f"kind: *a{levels - 1}"]) + "\n"


def _raw(path, data: bytes) -> bytes:
    """Send ``data`` (from a thread: the daemon may refuse before reading it all) and return
    the daemon's answer."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(60)
        s.connect(str(path))

        def send():
            try:
                s.sendall(data)
            except OSError:
                pass          # refused and closed before the end: expected for 5 MB
        t = threading.Thread(target=send, daemon=True)
        t.start()
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(65536)
            if not chunk:
                break
            buf += chunk
        t.join(10)
    return buf


def _fly_hop(tmp, during, *fly_args) -> dict:
    """The hop on firmware_sim --lockstep (ideal world; a 3 s lockstep timeout, so that a loaded
    machine does not lose periods) flown by ``mavreg fly``; ``during(fly, emu)`` meanwhile."""
    emu, url = start_emulator(tmp / "groundtruth.npz", "--lockstep", "--preset", "ideal", "--vehicle",
                              str(VEHICLE_IDEAL), "--lockstep-timeout", "3")
    out = tmp / "out"
    try:
        fly = mavreg("fly", str(HOP), "--vehicle", url, "--vehicle-lockstep", "--vehicle-params", str(VEHICLE_IDEAL),
                     "--controller", str(CONTROLLER), "--out", str(out), "--timeout-s", "240", *fly_args)
        try:
            extra = during(fly, emu)
        finally:
            code = fly.wait(300)
    finally:
        emu.stop()
    return {"code": code, "summary": json.loads((out / "summary.json").read_text()), "lines": fly.lines,
            "extra": extra}


def test_hostile_uploads_while_flying_are_refused_in_one_line_and_the_flight_lands(tmp_path):
    sock = tmp_path / "mavreg.sock"
    bomb = alias_bomb(10)                      # 530 bytes: hung the loader (3 GB in a minute)
    huge = json.dumps({"op": "upload", "name": "huge.yaml",
                       "yaml": "kind: maneuver\n" + "#" * (5 << 20)}).encode() + b"\n"

    def loop_ms():
        """(longest wall gap, most CPU of the loop's thread) between two ticks so far."""
        loop = request(sock, {"op": "status"}, 30)["status"]["loop"]
        return loop["max_tick_gap_ms"], loop["max_tick_cpu_ms"]

    def during(fly, emu):
        fly.wait_line("[takeoff] phase", 120)
        before = loop_ms()
        answers = {"malformed JSON": _raw(sock, b'{"op": "upload", "name": \n'),   # while flying
                   "5 MB": _raw(sock, huge)}
        # The bomb needs the planner worker, which runs at the lowest priority: the lockstep
        # vehicle waits while it is planned, or on a loaded machine the flight could end first.
        emu.p.send_signal(signal.SIGSTOP)
        try:
            answers["alias bomb"] = (json.dumps(request(sock, {"op": "upload", "name": "bomb.yaml",
                                                               "yaml": bomb}, 120)) + "\n").encode()
        finally:
            emu.p.send_signal(signal.SIGCONT)
        return answers, before, loop_ms()

    f = _fly_hop(tmp_path, during, "--socket", str(sock), "--stale-timeout-s", "300",
                 "--planner-memory-mib", "384", "--planner-cpu-s", "10")
    answers, before, after = f["extra"]
    assert f["code"] == 0 and f["summary"]["result"] == "ok", "\n".join(f["lines"][-30:])
    print()
    for what, raw in answers.items():
        assert raw.count(b"\n") == 1 and len(raw) < 1000, (what, raw[:200])
        resp = json.loads(raw)
        print(f"{what}: {resp}")
        assert resp["ok"] is False, resp
    assert "malformed request" in json.loads(answers["malformed JSON"])["reason"]
    assert "too large" in json.loads(answers["5 MB"])["reason"]
    bomb_resp = json.loads(answers["alias bomb"])
    assert bomb_resp["verdict"] == "rejected" and "bomb.yaml" in bomb_resp["reason"]
    st = f["summary"]["status"]
    assert st["uploads"] == {"accepted": 1, "rejected": 1}       # accepted: the flight itself
    assert st["loop"]["endpoint_refused"] == 2
    loop = st["loop"]
    print(f"control loop, longest gap between {loop['tick_ms']:.0f} ms ticks (most CPU of its thread): "
          f"{before[0]:.0f} ms ({before[1]:.0f}) before the hostile uploads, {after[0]:.0f} ms ({after[1]:.0f}) "
          f"after them, {loop['max_tick_gap_ms']:.0f} ms ({loop['max_tick_cpu_ms']:.0f}) over the flight, "
          f"in {loop['max_tick_gap_phase']}; wall {f['summary']['wall_time_s']:.1f} s")
