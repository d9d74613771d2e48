"""The control loop keeps running, every period, while an upload is planned in the worker.

firmware_sim in lockstep (ideal world: every period releases one complete sample; the
emulator waits up to 30 s of wall time for each period's command) and ``mavreg serve`` as
processes. A first upload makes the daemon take off; a second one is planned (seconds of
CPU in the worker, at the lowest priority) while the vehicle flies. Meanwhile the test
polls the daemon's status. Judged in vehicle time:

- while the second upload was being planned, the daemon answered status requests and
  the vehicle flew on: its count of state samples grew by many periods. A control loop
  blocked by planning would answer nothing and hold the lockstep emulator still;
- every state sample of the flight was answered by one command, in airborne phases.

Lockstep makes this independent of machine load: a loaded or descheduled process slows
the flight down in wall time but cannot make the daemon miss a period. The daemon's
stale-state timeout is raised to 30 s for the same reason (link-health policy is tested
elsewhere; here a slow machine must not abort the flight). A loaded machine also makes a
lowest-priority plan take long, during which lockstep flies many minutes of hold; so the
test keeps no per-period artifact (no .tlog, no recording, no emulator duration) and
judges from the daemon's counters.
"""
from __future__ import annotations

import signal
import sys
import threading
import time

import pytest

from mavreg.daemon.jobs.endpoint import request
from harness.processes import children, start_time, survivors
from tests.helpers.sitl import BARREL, Proc, mavreg

pytestmark = pytest.mark.sitl

MIN_PERIODS = 100      # 0.2 s of flight at 500 Hz; a blocked loop flies none while planning
AIRBORNE = ("takeoff", "hold", "run_in", "maneuver")
POLL_S = 0.02


def _status(sock) -> dict:
    return request(sock, {"op": "status"}, 60)["status"]


def test_control_loop_runs_every_period_while_planning(tmp_path):
    sock = tmp_path / "d.sock"
    emu = Proc([sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", "--quiet",
                "--lockstep", "--lockstep-timeout-s", "30", "--world", "ideal"])
    serve = None
    polls: list[dict] = []
    second: dict = {}
    try:
        url = emu.wait_line("firmware_sim listening on", 60).split()[-1].replace("udpin:", "udpout:")
        serve = mavreg("serve", "--vehicle", url, "--vehicle-lockstep", "--socket", str(sock), "--stale-timeout-s", "30")
        serve.wait_line("control endpoint", 120)
        workers = {p: start_time(p) for p in children(serve.p.pid)}
        first = request(sock, {"op": "upload", "name": "first", "yaml": BARREL.read_text()}, 900)
        assert first["ok"], first
        serve.wait_line("[takeoff] phase", 120)

        def upload():
            second.update(request(sock, {"op": "upload", "name": "second", "yaml": BARREL.read_text()}, 900))
        client = threading.Thread(target=upload, daemon=True)
        client.start()
        while client.is_alive():
            polls.append(_status(sock))
            time.sleep(POLL_S)
        client.join()
        final = _status(sock)
        serve.p.send_signal(signal.SIGINT)      # first: land at the next safe point
        serve.wait_line("signal: ", 60)
        code = serve.stop(signal.SIGINT, 60)    # second: stop at once
    finally:
        if serve is not None:
            serve.stop()
        emu.stop()
    assert second["ok"], second
    assert code == 0, serve.lines[-20:]
    assert survivors(workers) == []             # a clean exit stops the worker too

    during = [p for p in polls if p["planning"]]
    flown = during[-1]["counters"]["samples"] - during[0]["counters"]["samples"] if during else 0
    print(f"\nwhile planning: {len(during)} status replies, {flown} periods flown "
          f"({flown / 500:.1f} s of vehicle time), phases {sorted({p['phase'] for p in during})}")
    assert len(during) >= 2 and flown >= MIN_PERIODS
    assert all(p["phase"] in AIRBORNE for p in during)
    c = final["counters"]
    assert c["samples"] == c["actuator_sent"] > flown
    assert c["state_late"] == c["state_unmatched"] == 0
