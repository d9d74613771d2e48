"""End-to-end: a daemon flying the barrel roll on firmware_sim --lockstep receives hostile
uploads (malformed JSON, 5 MB, a YAML alias bomb, then every file of the hostile corpus in
tests/data/hostile) and flies on: each gets a one-line refusal
or rejection and the flight lands ok. The longest gaps between the daemon's control ticks
before, across and after the uploads are printed (issue 21: inputs that cannot hurt)."""
from __future__ import annotations

import json
import signal
import socket
import threading
from pathlib import Path

import pytest

from conftest import fly_lockstep
from tests.helpers.sitl import VEHICLE_IDEAL
from mavreg.daemon.jobs.endpoint import request

pytestmark = pytest.mark.sitl

CORPUS = sorted((Path(__file__).resolve().parents[1] / "data" / "hostile").glob("*.yaml"))


def _upload_corpus(sock) -> dict:
    """Each corpus file as an upload: its text if it is UTF-8, else its bytes as they are
    inside the request line (the endpoint must refuse that line)."""
    answers = {}
    for path in CORPUS:
        data = path.read_bytes()
        try:
            resp = request(sock, {"op": "upload", "name": path.name, "yaml": data.decode("utf-8")}, 60)
            answers[path.name] = (json.dumps(resp) + "\n").encode()
        except UnicodeDecodeError:
            answers[path.name] = _raw(sock, b'{"op": "upload", "name": "x.yaml", "yaml": "' + data + b'"}\n')
    return answers


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
            answers.update(_upload_corpus(sock))
        finally:
            emu.p.send_signal(signal.SIGCONT)
        return answers, before, loop_ms()

    # a 3 s lockstep timeout: a loaded machine cannot make the vehicle fly a period uncommanded
    f = fly_lockstep(tmp_path, ("--lockstep-timeout-s", "3"),
                     ("--socket", str(sock), "--stale-timeout-s", "300",
                      "--planner-memory-mib", "384", "--planner-cpu-s", "10"), during, vehicle=VEHICLE_IDEAL)
    answers, before, after = f["extra"]
    assert f["code"] == 0 and f["summary"]["result"] == "ok", "\n".join(f["lines"][-30:])
    print()
    for what, raw in answers.items():
        assert raw.count(b"\n") == 1 and len(raw) < 1000, (what, raw[:200])
        resp = json.loads(raw)
        if what in ("malformed JSON", "5 MB", "alias bomb"):
            print(f"{what}: {resp}")
        assert resp["ok"] is False, (what, resp)
    assert "malformed request" in json.loads(answers["malformed JSON"])["reason"]
    assert "too large" in json.loads(answers["5 MB"])["reason"]
    bomb_resp = json.loads(answers["alias bomb"])
    assert bomb_resp["verdict"] == "rejected" and "bomb.yaml" in bomb_resp["reason"]
    st = f["summary"]["status"]
    refused = sum(json.loads(a).get("verdict") == "refused" for a in answers.values())
    rejected = sum(json.loads(a).get("verdict") == "rejected" for a in answers.values())
    assert refused + rejected == len(answers) and len(answers) == len(CORPUS) + 3
    print(f"{len(CORPUS)} corpus files and 3 hostile requests: {rejected} rejected by the loader or planner, "
          f"{refused} refused by the endpoint, all one line; the flight flew on")
    assert st["uploads"] == {"accepted": 1, "rejected": rejected}       # accepted: the flight itself
    assert st["loop"]["endpoint_refused"] == refused
    loop = st["loop"]
    print(f"control loop, longest gap between {loop['tick_ms']:.0f} ms ticks (most CPU of its thread): "
          f"{before[0]:.0f} ms ({before[1]:.0f}) before the hostile uploads, {after[0]:.0f} ms ({after[1]:.0f}) "
          f"after them, {loop['max_tick_gap_ms']:.0f} ms ({loop['max_tick_cpu_ms']:.0f}) over the flight, "
          f"in {loop['max_tick_gap_phase']}; wall {f['summary']['wall_time_s']:.1f} s")
