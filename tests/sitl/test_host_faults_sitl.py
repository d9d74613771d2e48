"""The host misbehaves, end to end (issue 32, item 3): a full disk, a stepped wall clock.

Flights in lockstep on the bundled emulator (deterministic, independent of the machine's
load), judged on the emulator's recorded truth:

- every file ``mavreg fly`` writes is on a full disk (``/dev/full``: each write gives
  ``ENOSPC``): the flight is flown and landed ``ok``, exit 0, each file said once, and the
  summary reaches the user on standard output;
- the wall clock jumps by +1 h or -1 h as the maneuver begins (the injected clock,
  :attr:`mavreg.daemon.jobs.assembly.DaemonOptions.wall_s`): the flight is the same, bit for bit, as one
  without a jump; the signed link takes every frame; the ``.tlog``'s stamps step by nothing.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER
from tests.helpers.sitl import load_record, vehicle_samples
from tests.helpers.repo import ROOT
from tests.helpers.waiting import wait_until

pytestmark = pytest.mark.sitl

HOP = Path(__file__).with_name("signing_hop.yaml")
FULL = Path("/dev/full")
OUTPUTS = ("flight.tlog", "control.npz", "summary.json", "flight.png")


def _landed_ok(record: dict) -> None:
    """The truth: flown off the ground and back, disarmed on the ground at the end, no crash."""
    z = record["position_ned_m"][:, 2]
    assert z.min() < -1.0 and abs(z[-1]) < 0.05
    assert not bool(record["armed"][-1])


@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")
def test_fly_with_every_output_on_a_full_disk_lands_ok_and_says_each_once(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for name in OUTPUTS:
        (out / name).symlink_to(FULL)
    res = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "fly", str(HOP), "--lockstep", "--out", str(out)],
                         cwd=ROOT, capture_output=True, text=True, timeout=900)
    err = res.stderr.splitlines()
    assert res.returncode == 0, res.stderr[-3000:]
    for what, name in (("tlog", "flight.tlog"), ("control log", "control.npz"), ("summary", "summary.json"),
                       ("plot", "flight.png")):
        said = [ln for ln in err if ln.startswith(f"{what}: stopped writing {out / name}")]
        assert len(said) == 1, (what, said)
        assert "[Errno 28 ENOSPC] No space left on device" in said[0]
    assert "Traceback" not in res.stderr
    summary_line = [ln for ln in res.stdout.splitlines() if ln.startswith("summary.json: ")]
    assert len(summary_line) == 1
    summary = json.loads(summary_line[0].split(": ", 1)[1])
    assert summary["result"] == "ok" and summary["status"]["tlog"]["stopped"].startswith("tlog: stopped writing")
    assert "not written: summary.json, flight.png, flight.tlog, control.npz" in res.stdout
    _landed_ok(load_record(out / "groundtruth.npz"))


def _fly_in_process(tmp_path: Path, jumps: bool, monkeypatch) -> dict:
    """The hop in lockstep, signed, through :func:`mavreg.daemon.jobs.fly.fly` in this process; with
    ``jumps`` its wall clock jumps +1 h as the maneuver begins and -2 h (to an hour behind) as
    the landing begins."""
    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.daemon.jobs import app as daemon_app
    from mavreg.daemon.jobs import fly as fly_mod
    from mavreg.daemon.jobs.assembly import DaemonOptions, EmulatorOptions
    from mavreg.daemon.flight.supervisor import Phase
    tmp_path.mkdir()
    key = tmp_path / "mavlink.key"
    key.write_text(bytes(range(7, 39)).hex())
    key.chmod(0o600)
    state = {"daemon": None, "offset_s": 0.0, "jumped_at": {}}
    steps = {Phase.MANEUVER: 3600.0, Phase.LAND: -7200.0} if jumps else {}

    def wall_s() -> float:
        d = state["daemon"]
        if d is not None and d.supervisor.phase in steps and d.supervisor.phase not in state["jumped_at"]:
            state["jumped_at"][d.supervisor.phase] = d.supervisor.last_sample.time_s
            state["offset_s"] += steps[d.supervisor.phase]
        return time.time() + state["offset_s"]

    class Watched(daemon_app.Daemon):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            state["daemon"] = self
    monkeypatch.setattr(daemon_app, "Daemon", Watched)     # what assemble() builds
    out = tmp_path / "out"
    opts = DaemonOptions(vehicle=load_vehicle(DEFAULT_VEHICLE), controller=load_controller(REAL_CONTROLLER),
                         vehicle_url=None, emulator=EmulatorOptions(vehicle_file=DEFAULT_VEHICLE, lockstep=True),
                         maneuvers=((HOP.read_text(), str(HOP)),), out_dir=out, job_writes_outputs=True,
                         timeout_s=600.0, signing_key=key, tlog_clock="wall", wall_s=wall_s)
    started_s = time.time()
    code = fly_mod.fly(opts)
    saved = json.loads((tmp_path / "mavlink.key.mavreg-state.json").read_text())["timestamp"]
    return {"code": code, "summary": json.loads((out / "summary.json").read_text()),
            "record": load_record(out / "groundtruth.npz"), "jumped_at": state["jumped_at"],
            "tlog": vehicle_samples(out / "flight.tlog"),
            "signed_ahead_s": saved / 1e5 + 1_420_070_400 - started_s}


@pytest.mark.slow       # two lockstep flights (about 75 s); the writers' and clocks' unit tests are in the suite
def test_wall_clock_jumps_of_an_hour_mid_flight_change_nothing(tmp_path, monkeypatch):
    from mavreg.daemon.flight.supervisor import Phase
    ref = _fly_in_process(tmp_path / "steady", False, monkeypatch)
    jumped = _fly_in_process(tmp_path / "jumped", True, monkeypatch)
    for f in (ref, jumped):
        s = f["summary"]
        assert f["code"] == 0 and s["result"] == "ok", s["reason"]
        _landed_ok(f["record"])
        assert s["status"]["signing"]["accepted"] > 10_000
        assert all(s["status"]["signing"][k] == 0 for k in ("unsigned", "bad_signature", "replayed"))
        # the .tlog's stamps (the wall clock at the start, then the monotonic clock) never step
        d = np.diff(f["tlog"][:, 0])
        assert np.all(d >= 0) and np.max(d) < 60.0
    # the clock did jump: in the maneuver (10.0-13.1 s of the hop's vehicle time), then at the
    # landing; the signing timestamps took the hour ahead and did not go back with the clock
    assert 10.0 < jumped["jumped_at"][Phase.MANEUVER] < 13.2 < jumped["jumped_at"][Phase.LAND]
    assert jumped["signed_ahead_s"] > 3500.0 and ref["signed_ahead_s"] < 600.0
    # the same flight, sample for sample, as the one without a jump
    a, b = ref["record"], jumped["record"]
    n = min(len(a["t_s"]), len(b["t_s"]))
    dist = float(np.max(np.linalg.norm(a["position_ned_m"][:n] - b["position_ned_m"][:n], axis=1)))
    print(f"\n{len(b['t_s'])} samples against {len(a['t_s'])}; largest distance {dist:.3g} m; flight "
          f"{jumped['summary']['flight_time_s']:.3f} s against {ref['summary']['flight_time_s']:.3f} s")
    assert dist < 1e-3 and abs(len(a["t_s"]) - len(b["t_s"])) <= 5


def _status(sock) -> dict:
    from mavreg.daemon.jobs.endpoint import request
    return request(sock, {"op": "status"}, 60)["status"]


@pytest.mark.slow       # a cold barrel-roll plan killed, then two hops (one to five minutes)
@pytest.mark.skipif(not FULL.exists(), reason="no /dev/full on this system")
def test_serve_worker_killed_mid_plan_refuses_that_upload_and_flies_the_next(tmp_path):
    """``serve`` (its .tlog and control log on a full disk too) flies a hop and holds; a barrel
    roll is uploaded and its planner worker SIGKILLed while it plans: that upload is refused
    with the cause in one line, the vehicle holds on, and the next upload plans and flies."""
    import threading
    from mavreg.config.paths import maneuver_file
    from mavreg.daemon.jobs.endpoint import request
    from tests.helpers.sitl import Proc, mavreg
    sock, record = tmp_path / "d.sock", tmp_path / "groundtruth.npz"
    ctl = tmp_path / "control.npz"
    ctl.symlink_to(FULL)
    # a name of its own: never in the plan cache, so planning lasts seconds of the worker's CPU
    roll = maneuver_file("barrel_roll").read_text().replace("name: barrel_roll", f"name: roll_{time.time_ns()}")
    emu = Proc([sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", "--quiet", "--lockstep",
                "--lockstep-timeout-s", "30", "--record", str(record)])
    serve = None
    try:
        url = emu.wait_line("firmware_sim listening on", 60).split()[-1].replace("udpin:", "udpout:")
        serve = mavreg("serve", "--vehicle", url, "--vehicle-lockstep", "--socket", str(sock),
                       "--stale-timeout-s", "30", "--tlog", str(FULL), "--control-log", str(ctl))
        serve.wait_line("control endpoint", 300)
        assert request(sock, {"op": "upload", "name": "hop1", "yaml": HOP.read_text()}, 900)["ok"]
        wait_until(lambda: _status(sock)["done"] == ["hop"] and _status(sock)["phase"] == "hold", "first hop flown")
        answer: dict = {}
        client = threading.Thread(target=lambda: answer.update(
            request(sock, {"op": "upload", "name": "roll.yaml", "yaml": roll}, 900)), daemon=True)
        client.start()
        # the pool's own record of its worker, read while the upload is in it: no race with a restart
        st = wait_until(lambda: (s := _status(sock))["planner"]["busy"] and s, "the roll being planned")
        victim = st["planner"]["worker_pid"]
        os.kill(victim, signal.SIGKILL)
        client.join(600)
        after = _status(sock)
        second = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "upload", str(HOP), "--socket", str(sock)],
                                cwd=ROOT, capture_output=True, text=True, timeout=900)
        wait_until(lambda: _status(sock)["done"] == ["hop", "hop"] and _status(sock)["phase"] == "hold",
              "second hop flown")
        final = _status(sock)
        assert request(sock, {"op": "land"}, 60)["ok"]
        serve.wait_line("touched down and disarmed", 600)      # not the preflight's "vehicle disarmed"
        code = serve.wait(120) if serve.p.poll() is not None else serve.stop(signal.SIGINT, 120)
    finally:
        if serve is not None:
            serve.stop()
        emu.stop()
    print(f"\nrefusal: {answer}\nnext: {second.stdout.strip()}")
    assert answer["ok"] is False and answer["verdict"] == "refused"
    assert answer["reason"].startswith("the planner worker process died while planning 'roll.yaml' "
                                       "(killed by SIGKILL)") and "\n" not in answer["reason"]
    assert after["phase"] == "hold" and after["vehicle_armed"] and after["planner"]["restarts"] == 1
    assert after["planner"]["worker_pid"] != victim
    assert second.returncode == 0 and second.stdout.startswith("accepted:")
    assert final["uploads"] == {"accepted": 2, "rejected": 1}
    said = [ln for ln in serve.lines if "refused: the planner worker process died" in ln]
    assert len(said) == 1
    # said once for the flight; serve then opens the next flight's logs on the same paths and
    # may say it once more (one line per flight, never one per write)
    flown = serve.lines[:next((i for i, ln in enumerate(serve.lines) if ln.startswith("flight 2:")),
                              len(serve.lines))]
    stopped = [ln for ln in flown if ln.startswith("tlog: stopped writing /dev/full")]
    assert len(stopped) == 1 and final["tlog"]["stopped"] == stopped[0], [ln for ln in serve.lines if "stopped" in ln
                                                                          or ln.startswith("flight")]
    assert len([ln for ln in flown if ln.startswith(f"control log: stopped writing {ctl}")]) == 1
    assert len([ln for ln in serve.lines if ln.startswith("tlog: stopped writing /dev/full")]) <= 2
    assert code == 0, "\n".join(serve.lines[-20:])
    rec = load_record(record)
    _landed_ok(rec)
    # held between the two hops: one take-off, one landing (airborne from the first lift-off on)
    z = rec["position_ned_m"][:, 2]
    up = np.flatnonzero(z < -0.5)
    assert np.all(z[up[0]:up[-1]] < -0.3)


@pytest.mark.slow       # a real-time flight (about 25 s of wall time after the start) with both cores saturated
def test_real_time_flight_with_both_cores_saturated_mid_flight_lands(tmp_path):
    """The hop in real time on the bundled emulator (realistic world); as the maneuver begins
    four busy loops saturate both cores until the flight lands or ends. The flight completes
    ``ok`` or recovers, and lands; no motor is stopped in the air.

    The daemon runs as deploy/mavreg.service runs it, at real-time priority
    (``SCHED_FIFO`` 50: ``chrt -f 50``); its emulator, which stands for the autopilot's own
    processor, inherits it; the busy loops run at the default priority. At equal priority the
    daemon gets a sixth of a core and cannot fly, and at ``nice -10`` it was still starved for
    seconds on a shared host (docs/reliability.md, *Host faults*). Run it alone
    (``flock /tmp/px4.lock``): it is the load."""
    from tests.helpers.sitl import Proc
    if subprocess.run(["chrt", "-f", "50", "true"], capture_output=True).returncode != 0:
        pytest.skip("real-time priority (chrt -f 50) is not permitted here: it takes root or CAP_SYS_NICE "
                    "and an RT budget in the container")
    out = tmp_path / "out"
    fly = Proc(["chrt", "-f", "50", sys.executable, "-m", "mavreg.cli.main", "fly", str(HOP), "--out", str(out),
                "--timeout-s", "300"])
    hogs: list[subprocess.Popen] = []
    try:
        fly.wait_line("maneuver 'hop' begins", 600)
        hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(4)]
        wait_until(lambda: fly.p.poll() is not None or any(w in ln for ln in fly.lines[-50:] for w in
                                                     ("landing from", "[aborted]", "touched down")),
              "the landing", 300)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
        code = fly.wait(600)
    summary = json.loads((out / "summary.json").read_text())
    kinds = [e["kind"] for e in summary["events"]]
    st = summary["status"]
    print(f"\nresult {summary['result']} ({summary['reason'] or 'ok'}); touchdown "
          f"{summary['touchdown_speed_m_s']}; gaps {st['counters'].get('gaps')}, gap commands "
          f"{st['counters'].get('gap_commands')}; maneuver latency {summary['maneuver_latency_ms']}; longest tick "
          f"gap {st['loop']['max_tick_gap_ms']:.0f} ms in {st['loop']['max_tick_gap_phase']}; true max error "
          f"{(summary['ground_truth'] or {}).get('max_m')}")
    assert "motors_stopped" not in kinds
    assert summary["result"] == "ok" or "recovered" in kinds, summary["reason"]
    assert code == (0 if summary["result"] == "ok" else 1)
    assert summary["touchdown_speed_m_s"] < 1.0
    _landed_ok(load_record(out / "groundtruth.npz"))
