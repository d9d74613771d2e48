"""The default controller in the realistic world, through ``mavreg experiment robustness``
(lockstep, fixed seed, judged on the emulator's ground truth): the paper's 8 N gust on the
run-up at speed and 7 N rotors are flown ``ok``, within the issue's figures (issue 18).
Two jobs: the gust's reference flight and the 7 N flight fly side by side (lockstep: the
results do not depend on it), then the gust flight."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest
from tests.helpers.sitl import RECORD_FIELDS

pytestmark = [pytest.mark.sitl, pytest.mark.lockstep]   # see pyproject.toml's markers


def test_the_run_up_gust_and_7n_rotors_are_flown_ok_with_the_defaults(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "experiment", "robustness", "--cells",
                           "gust-run-up,rotors-7n", "--flights", "1", "--jobs", "2", "--seed", "0",
                           "--out", str(out)], capture_output=True, text=True, timeout=400)
    runs = {m["cell"]: m for m in json.loads((out / "results.json").read_text())["runs"]}
    gust, sat = runs["gust-run-up"], runs["rotors-7n"]
    for m in (gust, sat):                          # the campaign's record of a flown flight
        assert set(RECORD_FIELDS) <= set(m), set(RECORD_FIELDS) - set(m)
        assert (out / "runs" / f"{m['index']:03d}" / "summary.json").exists()
        assert m["flight_time_s"] > 10.0 and m["loop_max_error_m"] <= m["maneuver_max_error_m"]
        assert m["lowest_altitude_m"] > 1.0 and m["max_touchdown_speed_m_s"] < 1.0
        assert m["ground_impact"] is False and m["motors_stopped_in_air"] is False
        assert m["first_bound"] is None and m["cause"] == ""
    print(f"\ngust: {gust['maneuver_max_error_m']:.3f} m, overspeed {gust['overspeed_m_s']:.3f} m/s; "
          f"7 N: loop {sat['loop_max_error_m']:.3f} m")
    # 8 N against the run-up for 1 s at 8 m/s: on the path within 10 cm, no catch-up, ok
    assert gust["gust_force_n"] is not None and max(abs(f) for f in gust["gust_force_n"]) == pytest.approx(8.0)
    assert gust["result"] == "ok" and gust["safety"] == "ok", gust["cause"]
    assert gust["maneuver_max_error_m"] <= 0.10 and gust["overspeed_m_s"] <= 0.3
    # rotors that give 7 N (the controller told so): the loop within 40 cm, landed ok
    assert sat["saturation_n"] == 7.0
    assert sat["result"] == "ok" and sat["safety"] == "ok", sat["cause"]
    assert sat["loop_max_error_m"] <= 0.40
    assert proc.returncode == 0, proc.stderr[-2000:]
