"""No process the daemon starts outlives it, even when the daemon is SIGKILLed.

``mavreg serve`` is killed while its planner worker is computing an upload; ``mavreg fly``
(which also starts the emulator) is killed in flight. Their children are identified from
/proc before the kill; afterwards /proc is polled (at most 10 s) until every one is gone.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import time

import pytest

from mavreg.daemon.jobs.endpoint import request
from harness.processes import children, cmdline, start_time, survivors
from tests.helpers.sitl import BARREL, mavreg, start_emulator

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")]


def _tree(pid: int) -> dict[int, int | None]:
    """{pid: start time} of every descendant of ``pid``."""
    out, todo = {}, children(pid)
    while todo:
        p = todo.pop()
        out[p] = start_time(p)
        todo += children(p)
    return out


def _kill_and_check(proc, tree: dict[int, int | None]) -> list[str]:
    """SIGKILL ``proc``; return the command lines of its descendants still alive after 10 s."""
    proc.p.kill()
    t0 = time.monotonic()
    proc.p.wait(30)
    left = survivors(tree)
    print(f"\n{len(tree)} children; {len(left)} left {time.monotonic() - t0:.2f} s after the SIGKILL")
    names = [f"{p}: {cmdline(p)}" for p in left]
    for p in left:   # a failing test must not leave them behind either
        os.kill(p, signal.SIGKILL)
    return names


def test_sigkilled_serve_mid_plan_leaves_no_worker(tmp_path):
    sock = tmp_path / "d.sock"
    emu, url = start_emulator(tmp_path / "gt.npz", "--lockstep", "--lockstep-timeout-s", "30",
                              "--world", "ideal", "--duration-s", "600")
    serve = mavreg("serve", "--vehicle", url, "--vehicle-lockstep", "--socket", str(sock), "--stale-timeout-s", "30")
    upload: dict = {}

    def send():
        try:
            upload["reply"] = request(sock, {"op": "upload", "name": "b", "yaml": BARREL.read_text()}, 600)
        except OSError as exc:   # expected: the daemon dies before it answers
            upload["error"] = exc
    client = threading.Thread(target=send, daemon=True)
    try:
        serve.wait_line("control endpoint", 120)
        tree = _tree(serve.p.pid)
        workers = [p for p in tree if "spawn_main" in cmdline(p)]
        assert len(workers) == 1, {p: cmdline(p) for p in tree}
        client.start()
        deadline = time.monotonic() + 120
        while request(sock, {"op": "status"}, 30)["status"]["planning"] == 0:
            assert time.monotonic() < deadline, "the upload never started planning"
            time.sleep(0.02)
        planning_at_kill = "reply" not in upload
        left = _kill_and_check(serve, tree)
    finally:
        serve.stop()
        emu.stop()
    client.join(30)
    assert planning_at_kill, "the plan finished before the kill; the test did not test it"
    assert "reply" not in upload
    assert left == []


def test_sigkilled_fly_leaves_no_emulator_and_no_worker(tmp_path):
    fly = mavreg("fly", str(BARREL), "--lockstep", "--out", str(tmp_path / "out"), "--timeout-s", "300")
    try:
        fly.wait_line("[takeoff] phase", 600)   # planning first, at the lowest priority
        tree = _tree(fly.p.pid)
        kinds = {p: cmdline(p) for p in tree}
        assert sum("firmware_sim" in c for c in kinds.values()) == 1, kinds
        assert sum("spawn_main" in c for c in kinds.values()) == 1, kinds
        left = _kill_and_check(fly, tree)
    finally:
        fly.stop()
    assert left == []
