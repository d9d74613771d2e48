"""``mavreg experiment robustness`` end to end: two lockstep flights through the real command."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.sitl

RECORD_FIELDS = ("result", "reason", "first_bound", "bound_phase", "action", "maneuver_max_error_m",
                 "loop_max_error_m", "max_attitude_error_deg", "lowest_altitude_m", "max_touchdown_speed_m_s",
                 "ground_impact", "motors_stopped_in_air", "motors_stopped_event_t_s", "flight_time_s",
                 "safety", "cause", "seed", "emulator_args")


def test_a_baseline_and_a_no_timesync_flight_are_judged_and_written(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "experiment", "robustness", "--cells",
                           "baseline,no-timesync", "--flights", "1", "--jobs", "1", "--seed", "3",
                           "--out", str(out)], capture_output=True, text=True, timeout=240)
    res = json.loads((out / "results.json").read_text())
    base, nots = res["runs"]
    assert proc.returncode == (0 if base["ok"] and nots["ok"] else 1), proc.stderr
    assert {f.name for f in out.iterdir()} >= {"results.json", "results.md", "robustness_cells.png", "runs"}
    for m in (base, nots):
        assert set(RECORD_FIELDS) <= set(m), set(RECORD_FIELDS) - set(m)
        assert (out / "runs" / f"{m['index']:03d}" / "summary.json").exists()
        assert not list((out / "runs" / f"{m['index']:03d}").glob("*.npz"))      # not kept by default
    assert base["cell"] == "baseline" and base["emulator_args"] == []
    assert base["result"] in ("ok", "failed") and base["flight_time_s"] > 10.0
    assert base["maneuver_max_error_m"] is not None and base["max_touchdown_speed_m_s"] is not None
    assert base["loop_max_error_m"] <= base["maneuver_max_error_m"]
    if base["result"] == "ok":                      # the daemon's word and the truth's agree
        assert base["safety"] == "ok" and base["cause"] == "" and base["first_bound"] is None
        assert base["maneuver_max_error_m"] < 0.5 and base["lowest_altitude_m"] > 1.0
        assert base["max_touchdown_speed_m_s"] < 1.0
        assert base["ground_impact"] is False and base["motors_stopped_in_air"] is False
    else:
        assert base["safety"] != "ok" and base["first_bound"] and base["cause"]
    assert nots["emulator_args"] == ["--no-timesync"] and nots["seed"] == base["seed"]   # common noise
    # no TIMESYNC and no fixed_delay_s: refused on the ground, in one line that says what to set
    assert nots["safety"] == "failed, safe" and nots["first_bound"] == "gate_no_timesync"
    assert nots["bound_phase"] == "preflight" and "fixed_delay_s" in nots["cause"]
    assert nots["lowest_altitude_m"] is None or nots["lowest_altitude_m"] < 0.05
    summary = res["summary"]
    assert summary["runs"] == 2 and summary["flights_per_cell"] == 1
    assert list(summary["by_cell"]) == ["baseline", "no-timesync"]
    assert res["sitl"]["world"] == "realistic" and res["controller"].endswith("realistic.yaml")
    md = (out / "results.md").read_text()
    assert "## Per cell" in md and "| baseline |" in md and "robustness_cells.png" in md
