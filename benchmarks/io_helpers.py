"""Shared pieces of the benchmarks: figure records, the repository's files, processes.

A figure is a dict ``{"value", "baseline", "ratio", "target", "met", "unit", "note"}``;
``ratio`` is always "how many times better than the baseline" (value / baseline when higher
is better, baseline / value when lower is better), None when either is missing; ``met``
says whether the value reaches the target (None without a target).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from mavreg.config.paths import PARAMS_DIR
from mavreg.config.vehicle import G

REPO = Path(__file__).resolve().parents[1]
BARREL = PARAMS_DIR / "maneuvers/barrel_roll.yaml"
VEHICLE = PARAMS_DIR / "vehicles/mk_quadro.yaml"
PAPER_CONTROLLER = PARAMS_DIR / "controller/paper_lqr.yaml"
REALISTIC_CONTROLLER = PARAMS_DIR / "controller/realistic.yaml"
HOVER = 0.749 * G / 4 / 12.0
"""Per-rotor hover command of the MK-Quadro, as a fraction of the maximum thrust."""


def figure(value, baseline=None, *, target=None, unit: str, note: str = "", higher_is_better: bool) -> dict:
    """One figure record (see the module docstring)."""
    ratio = met = None
    if value is not None and baseline is not None and value > 0 and baseline > 0:
        ratio = value / baseline if higher_is_better else baseline / value
    if value is not None and target is not None:
        met = bool(value >= target if higher_is_better else value <= target)
    return {"value": value, "baseline": baseline, "ratio": ratio, "target": target, "met": met, "unit": unit,
            "note": note}


def percentile(values, q: float) -> float | None:
    """The q-th percentile (None for no values)."""
    return float(np.percentile(np.asarray(values, dtype=float), q)) if len(values) else None


def env_with_io(io: str) -> dict:
    """The environment for a child process using the ``fast`` or ``reference`` I/O path."""
    env = dict(os.environ)
    env["MAVREG_IO"] = io
    env["PYTHONUNBUFFERED"] = "1"
    env.setdefault("MPLBACKEND", "Agg")
    return env


def start_emulator(io: str, *args: str) -> tuple[subprocess.Popen, int]:
    """``firmware_sim`` on a free loopback port with the ``io`` path; returns (process, port)."""
    proc = subprocess.Popen([sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", "--quiet",
                             *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=REPO,
                            env=env_with_io(io))
    line = proc.stdout.readline()
    if not line.startswith("firmware_sim listening on udpin:"):
        stop(proc)
        raise RuntimeError(f"firmware_sim did not start: {line!r}")
    return proc, int(line.strip().rsplit(":", 1)[1])


def stop(proc: subprocess.Popen, timeout_s: float = 20.0) -> int:
    """SIGINT, then SIGKILL if the process does not exit; closes its pipes."""
    if proc.poll() is None:
        proc.send_signal(2)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    for f in (proc.stdout, proc.stderr):
        if f is not None:
            f.close()
    return proc.returncode


def read_tlog(path: Path):
    """(wall time s, source component, message id) of every frame of a ``.tlog``."""
    raw = Path(path).read_bytes()
    out = []
    i, n = 0, len(raw)
    while i + 8 + 12 <= n:
        t_us = int.from_bytes(raw[i:i + 8], "big")
        f = i + 8
        if raw[f] == 0xFD:
            ln = 12 + raw[f + 1] + (13 if raw[f + 2] & 1 else 0)
            out.append((t_us * 1e-6, raw[f + 6], raw[f + 7] | (raw[f + 8] << 8) | (raw[f + 9] << 16)))
        elif raw[f] == 0xFE:
            ln = 8 + raw[f + 1]
            out.append((t_us * 1e-6, raw[f + 4], raw[f + 5]))
        else:
            break
        i = f + ln
    return out
