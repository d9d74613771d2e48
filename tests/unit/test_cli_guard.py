"""A closed pipe or a Ctrl-C ends every command with one line and a conventional status,
never a traceback (mavreg.cli.guard)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from mavreg.config.paths import maneuver_file
from mavreg.cli.guard import EXIT_BROKEN_PIPE, EXIT_INTERRUPTED

BARREL = str(maneuver_file("barrel_roll"))


def _mavreg(*args):
    return [sys.executable, "-m", "mavreg.cli.main", *args]


@pytest.mark.parametrize("args", [("plan", BARREL, "--json"), ("plan", BARREL), ("--help",)],
                         ids=["plan-json", "plan", "help"])
def test_closed_pipe_exits_141_without_a_traceback(args):
    proc = subprocess.Popen(_mavreg(*args), stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()                     # the reader has gone: every write is EPIPE
    err = proc.stderr.read().decode()
    rc = proc.wait(timeout=120)
    assert "Traceback" not in err and "Exception ignored" not in err, err
    assert rc == (0 if args == ("--help",) else EXIT_BROKEN_PIPE) or rc == EXIT_BROKEN_PIPE


def _interrupt_when_started(cmd, marker: str, tmp_path, timeout_s: float = 120.0):
    """Start ``cmd`` in a process group of its own, wait until its standard error or output
    shows ``marker`` (it is running, not loading), then Ctrl-C the group as a terminal does."""
    out, err = tmp_path / "out.txt", tmp_path / "err.txt"
    with open(out, "wb") as fo, open(err, "wb") as fe:
        # A terminal's Ctrl-C reaches a foreground command with SIGINT at its default; a
        # test run started in the background (nohup ... &) ignores SIGINT, and its children
        # inherit that, so the command is started with the default restored.
        proc = subprocess.Popen(cmd, stdout=fo, stderr=fe, start_new_session=True,
                                env=dict(os.environ, PYTHONUNBUFFERED="1"),
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        deadline = time.monotonic() + timeout_s
        while marker not in out.read_text() + err.read_text():
            assert proc.poll() is None, f"ended before {marker!r}: {err.read_text()}"
            assert time.monotonic() < deadline, f"no {marker!r} in {timeout_s} s"
            time.sleep(0.05)
        os.killpg(proc.pid, signal.SIGINT)
        rc = proc.wait(timeout=60)
    return rc, err.read_text()


def test_ctrl_c_in_simulate(tmp_path):
    rc, err = _interrupt_when_started(_mavreg("simulate", BARREL, "--laps", "40"),
                                      "planned", tmp_path)
    assert rc == EXIT_INTERRUPTED and "Traceback" not in err, err
    assert err.strip().endswith("mavreg: interrupted")


@pytest.mark.slow          # 23 s: a pool of spawned workers starts before the Ctrl-C
def test_ctrl_c_in_an_experiment_with_workers(tmp_path):
    rc, err = _interrupt_when_started(
        _mavreg("experiment", "paper-group1", "--jobs", "2", "--out", str(tmp_path / "exp")),
        "paper-group1", tmp_path)
    assert rc == EXIT_INTERRUPTED and "Traceback" not in err, err
