"""The control loop keeps its rate while an upload is planned in the worker process.

Real time (no lockstep): firmware_sim at 500 Hz and ``mavreg serve`` as processes. A
first upload makes the daemon take off; a second one is planned (seconds of CPU in the
worker) while the hover LQR flies. Judged from the daemon's .tlog by vehicle time: every
state sample of the planning window is answered by one command, with no gap.
"""
from __future__ import annotations

import signal
import time

import numpy as np
import pytest
from pymavlink import mavutil

from mavreg.daemon.endpoint import request
from sitl_helpers import BARREL, mavreg, start_emulator

pytestmark = pytest.mark.sitl


def test_control_rate_unchanged_while_planning(tmp_path):
    sock, tlog = tmp_path / "d.sock", tmp_path / "d.tlog"
    emu, url = start_emulator(tmp_path / "gt.npz", "--duration-s", "120")
    serve = mavreg("serve", "--vehicle", url, "--socket", str(sock), "--tlog", str(tlog))
    try:
        serve.wait_line("control endpoint", 60)
        first = request(sock, {"op": "upload", "name": "first", "yaml": BARREL.read_text()}, 120)
        assert first["ok"], first
        serve.wait_line("[takeoff] phase", 60)
        time.sleep(1.0)
        t_req = time.time()
        second = request(sock, {"op": "upload", "name": "second", "yaml": BARREL.read_text()}, 120)
        t_resp = time.time()
        assert second["ok"], second
        status = request(sock, {"op": "status"}, 10)["status"]
        assert status["phase"] == "takeoff"
    finally:
        serve.stop(signal.SIGINT, 1.0)   # first: land at the next safe point
        serve.stop(signal.SIGINT)        # second: stop at once
        emu.stop()
    conn = mavutil.mavlink_connection(str(tlog))
    samples, answered, last_t = [], [], None
    while (m := conn.recv_match()) is not None:
        if not t_req <= m._timestamp <= t_resp:
            continue
        if m.get_type() == "ATTITUDE_QUATERNION":
            samples.append(m.time_boot_ms)
            last_t = m.time_boot_ms
        elif m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" and last_t is not None:
            answered.append(last_t)
    samples, answered = np.array(samples), np.unique(answered)
    gaps_ms = np.diff(answered)
    print(f"\nplanning window: {len(samples)} samples, {len(answered)} answered, "
          f"largest gap {gaps_ms.max()} ms of vehicle time; latency {status['latency_ms']}")
    assert len(samples) > 500                     # the window lasted seconds of 500 Hz telemetry
    assert len(answered) >= 0.98 * len(samples)
    assert gaps_ms.max() <= 10
