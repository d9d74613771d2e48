"""The daemon's per-sample chain, compiled against pure, on recorded closed-loop samples.

The kernels are each held to their reference on seeded cases (``test_predictor.py``,
``test_disturbance_kernel.py``, ``test_fastpath.py``, ``test_hover.py``); here the whole chain
the daemon runs per sample, the forecaster (the observer's own prediction from the previous
sample, its Kalman update, the prediction across the link), the controller on the forecast
(hover LQR with the estimate fed forward, or the maneuver regulator) and the command's
bookkeeping, is replayed on the samples of real closed-loop flights (the design model with
``realistic.yaml``: rotors lagging 20 ms, the state 14 ms late, a 0.6 N side force) twice, in
fresh processes, compiled and with ``MAVREG_PURE=1``, and every output compared. The replay
adds what the flights' own timing lacks (the chain and its gaps:
:mod:`tests.helpers.controller_replay`): the observer off for the first samples (on the
ground), telemetry gaps (samples dropped, so commands switch inside a horizon and the
observer sees gaps past its limit), gap-filling predictions past the delay
(:meth:`Forecaster.ahead`, some past the horizon cap), and a second answer to one sample.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from harness import controller_flight as flight

from tests.helpers.repo import ROOT as REPO

@pytest.fixture(scope="module")
def flights(tmp_path_factory):
    """The hover (3 s: take-off ramp and hold) and the barrel roll's run-up end and roll
    (4 to 9.5 s), as saved sample files."""
    setup = flight.Setup()
    tmp = tmp_path_factory.mktemp("replay")
    out = {}
    for phase, duration_s, t_from in (("hover", 3.0, 0.0), ("maneuver", 9.5, 4.0)):
        samples = [s for s in flight.fly(setup, phase, duration_s) if s[0] >= t_from - 1e-9]
        # the regulator starts near the node closest to the first replayed sample
        near = np.argmin(np.linalg.norm(setup.plan.x[:, :3] - samples[0][1][:3], axis=1))
        s0 = float(setup.plan.s[near])
        path = tmp / f"{phase}.npz"
        np.savez(path, t=np.array([s[0] for s in samples]), x=np.array([s[1] for s in samples]),
                 R=np.array([s[2] for s in samples]), delay=np.array([s[3] for s in samples]), s0=s0)
        out[phase] = path
    return out


def _both_paths(phase: str, samples_path: Path, tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    res = []
    for pure in ("0", "1"):
        out = tmp_path / f"{phase}{pure}.npy"
        subprocess.run([sys.executable, "-m", "tests.helpers.controller_replay", phase, str(samples_path), str(out)], check=True,
                       timeout=600, cwd=REPO, env=dict(os.environ, MAVREG_PURE=pure))
        res.append(np.load(out))
    return res[0], res[1]


def _relative(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """|a - b| per column over (1 + the column's largest magnitude)."""
    fin = np.isfinite(b)
    assert np.array_equal(fin, np.isfinite(a))
    return np.where(fin, np.abs(np.nan_to_num(a) - np.nan_to_num(b)), 0.0).max(axis=0) / (
        1.0 + np.nanmax(np.abs(b), axis=0))


def test_hover_chain_compiled_agrees_with_pure(flights, tmp_path):
    fast, pure = _both_paths("hover", flights["hover"], tmp_path)
    assert fast.shape == pure.shape and fast.shape[0] > 1400
    assert _relative(fast, pure).max() < 1e-12
    est = pure[-1, 38:44]                     # the filter's (c_xy, c_z, F_n, F_e, F_d, k)
    assert np.linalg.norm(est[2:4] - np.array(flight.SIDE_FORCE_N[:2])) < 0.2      # the observer found the force
    assert np.isnan(pure[:, -16:]).any() and np.isfinite(pure[:, -16:]).any()   # past the cap and within


def test_barrel_roll_chain_compiled_agrees_with_pure(flights, tmp_path):
    fast, pure = _both_paths("maneuver", flights["maneuver"], tmp_path)
    assert fast.shape == pure.shape and fast.shape[0] > 2500
    assert np.abs(pure[:, 9:12]).max() > 3.0                  # the roll's rates are in the replay
    assert _relative(fast, pure).max() < 1e-12
