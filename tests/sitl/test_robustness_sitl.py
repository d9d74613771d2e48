"""``mavreg experiment robustness`` end to end through the real command: a vehicle without
TIMESYNC is refused on the ground, and the campaign's files are written. The flown cells'
records are checked in test_defaults_sitl.py (the gust and the 7 N rotors)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.helpers.sitl import RECORD_FIELDS

pytestmark = pytest.mark.sitl


def test_a_vehicle_without_timesync_is_refused_and_the_campaign_written(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "experiment", "robustness", "--cells",
                           "no-timesync", "--flights", "1", "--jobs", "1", "--seed", "3",
                           "--out", str(out)], capture_output=True, text=True, timeout=240)
    res = json.loads((out / "results.json").read_text())
    (nots,) = res["runs"]
    assert proc.returncode == 1, proc.stderr                      # a flight that is not ok
    assert {f.name for f in out.iterdir()} >= {"results.json", "results.md", "robustness_cells.png", "runs"}
    assert set(RECORD_FIELDS) <= set(nots), set(RECORD_FIELDS) - set(nots)
    assert (out / "runs" / f"{nots['index']:03d}" / "summary.json").exists()
    assert not list((out / "runs" / f"{nots['index']:03d}").glob("*.npz"))      # not kept by default
    # no TIMESYNC and no fixed_delay_s: refused on the ground, in one line that says what to set
    assert nots["emulator_args"] == ["--no-timesync"]
    assert nots["safety"] == "failed, safe" and nots["first_bound"] == "gate_no_timesync"
    assert nots["bound_phase"] == "preflight" and "fixed_delay_s" in nots["cause"]
    assert nots["lowest_altitude_m"] is None or nots["lowest_altitude_m"] < 0.05
    assert nots["motors_stopped_in_air"] is False and not nots["ground_impact"]
    summary = res["summary"]
    assert summary["runs"] == 1 and summary["flights_per_cell"] == 1
    assert list(summary["by_cell"]) == ["no-timesync"]
    assert res["sitl"]["world"] == "realistic" and res["controller"].endswith("realistic.yaml")
    md = (out / "results.md").read_text()
    assert "## Per cell" in md and "| no-timesync |" in md and "robustness_cells.png" in md
