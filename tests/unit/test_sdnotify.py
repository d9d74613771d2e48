"""systemd's readiness protocol (mavreg.daemon.jobs.sdnotify) and the service unit (deploy/)."""
from __future__ import annotations

import os
import re
import shlex
import shutil
import socket
import subprocess

import pytest

from mavreg.daemon.jobs.sdnotify import Notifier
from tests.helpers.repo import ROOT

UNIT = ROOT / "deploy" / "mavreg.service"


@pytest.fixture
def listener(tmp_path):
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    path = str(tmp_path / "notify")
    sock.bind(path)
    sock.settimeout(10.0)
    yield sock, path
    sock.close()


def test_ready_is_one_datagram_with_the_status(listener):
    sock, path = listener
    notifier = Notifier({"NOTIFY_SOCKET": path})
    assert notifier.enabled and notifier.ready("flying from udpin:0.0.0.0:14540\nsecond line")
    assert sock.recv(4096).decode() == "READY=1\nSTATUS=flying from udpin:0.0.0.0:14540 second line"
    assert notifier.stopping("bye")
    assert sock.recv(4096).decode() == "STOPPING=1\nSTATUS=bye"


def test_an_abstract_socket_is_named_with_an_at_sign():
    name = f"mavreg-test-{os.getpid()}"
    with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as sock:
        sock.bind("\0" + name)
        sock.settimeout(10.0)
        assert Notifier({"NOTIFY_SOCKET": "@" + name}).status("compiling")
        assert sock.recv(4096) == b"STATUS=compiling"


def test_outside_systemd_nothing_is_sent_and_a_gone_socket_is_no_error(tmp_path):
    quiet = Notifier({})
    assert not quiet.enabled and not quiet.ready("x") and not quiet.watchdog()
    gone = Notifier({"NOTIFY_SOCKET": str(tmp_path / "nobody-listens")})
    assert gone.enabled and gone.ready("x") is False


def test_the_watchdog_period_is_half_the_units_and_only_for_this_process(listener):
    sock, path = listener
    assert Notifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "5000000"}).watchdog_s == 2.5
    mine = Notifier({"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "5000000", "WATCHDOG_PID": str(os.getpid())})
    assert mine.watchdog() and sock.recv(4096) == b"WATCHDOG=1"
    for env in ({"WATCHDOG_USEC": "5000000", "WATCHDOG_PID": "1"}, {"WATCHDOG_USEC": "soon"},
                {"WATCHDOG_USEC": "0"}):
        assert Notifier({"NOTIFY_SOCKET": path, **env}).watchdog_s is None


def _unit_settings() -> dict[str, list[str]]:
    settings: dict[str, list[str]] = {}
    for line in UNIT.read_text().splitlines():
        if "=" in line and not line.startswith(("#", "[")):
            key, value = line.split("=", 1)
            settings.setdefault(key, []).append(value)
    return settings


def test_the_unit_is_a_notify_service_restarted_on_failure_that_logs_to_the_journal():
    s = _unit_settings()
    assert s["Type"] == ["notify"] and s["Restart"] == ["on-failure"]
    assert s["StandardOutput"] == ["journal"] and s["StandardError"] == ["journal"]
    assert float(s["WatchdogSec"][0]) > 0 and s["NotifyAccess"] == ["main"]


def test_the_units_command_line_is_one_mavreg_serve_accepts(tmp_path):
    from mavreg.cli.main import build_parser
    command = _unit_settings()["ExecStart"][0]
    script = shlex.split(command)[-1]                       # /bin/sh -c '<script>'
    words = shlex.split(re.sub(r"\$\(date[^)]*\)", "20260101-000000", script.replace("%%", "%")))
    assert words[0] == "exec" and words[1].endswith("/mavreg") and words[2] == "serve"
    env = {"MAVREG_VEHICLE": _unit_settings()["Environment"][-1].split("=", 1)[1],
           "LOGS_DIRECTORY": str(tmp_path), "MAVREG_SERVE_ARGS": ""}     # systemd makes the logs dir
    argv = [w for w in (re.sub(r"\$(\w+)", lambda m: env[m.group(1)], w) for w in words[2:]) if w]
    args = build_parser()[0].parse_args(argv)
    assert args.vehicle == "serial:/dev/ttyAMA0:921600" and args.out.startswith(f"{tmp_path}/serve-")
    assert args.tlog is None and args.control_log is None          # the output directory, not the old files


def test_systemd_analyze_verifies_the_unit(tmp_path):
    tool = shutil.which("systemd-analyze")
    if tool is None:
        pytest.skip("systemd-analyze is not installed here (Debian: apt-get install systemd)")
    copy = tmp_path / "mavreg.service"
    copy.write_text(UNIT.read_text())
    done = subprocess.run([tool, "verify", str(copy)], capture_output=True, text=True, timeout=120)
    complaints = [line for line in (done.stdout + done.stderr).splitlines() if "mavreg.service" in line]
    assert done.returncode == 0 and complaints == [], "\n".join(complaints) or done.stderr


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_serve_says_ready_once_it_listens_feeds_the_watchdog_and_says_stopping(listener, tmp_path):
    """``mavreg serve`` under a fake systemd: STATUS lines while it starts, READY=1 once the
    link is open and the endpoint listens (the socket exists by then), WATCHDOG=1 from its
    loop, STOPPING=1 on SIGTERM, exit 0. No vehicle answers: it waits, and says so."""
    import signal
    import sys
    sock, path = listener
    endpoint = tmp_path / "d.sock"
    env = {**os.environ, "NOTIFY_SOCKET": path, "WATCHDOG_USEC": "400000", "MAVREG_PLAN_CACHE": "off"}
    proc = subprocess.Popen([sys.executable, "-m", "mavreg.cli.main", "serve", "--socket", str(endpoint),
                             "--vehicle", f"udpout:127.0.0.1:{_free_udp_port()}"], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    got: list[str] = []
    try:
        sock.settimeout(300.0)              # a cold numba cache compiles first
        while "READY=1" not in got:
            got += sock.recv(4096).decode().splitlines()
        assert endpoint.exists() and any(g.startswith("STATUS=") for g in got)
        sock.settimeout(30.0)
        while "WATCHDOG=1" not in got or not any("waiting for the vehicle" in g for g in got):
            got += sock.recv(4096).decode().splitlines()
        proc.send_signal(signal.SIGTERM)
        while "STOPPING=1" not in got:
            got += sock.recv(4096).decode().splitlines()
        assert proc.wait(60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
