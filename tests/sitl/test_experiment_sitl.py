"""One run of paper-group1 via sitl: the daemon and firmware_sim in lockstep, judged by the truth."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from mavreg.config.controller import load_controller
from mavreg.experiments.campaign import run_campaign
from mavreg.experiments.definitions import build_experiment, paper_group1, paper_group2
from mavreg.experiments.via_sitl import FLIGHT_FILES, fly_command, prepare_sitl_files

pytestmark = pytest.mark.sitl


def test_the_fly_command_gives_the_plant_to_the_emulator_and_the_offset_to_the_daemon(tmp_path, monkeypatch):
    g1 = paper_group1(0, samples=1)
    g2 = paper_group2(0)
    monkeypatch.chdir(tmp_path)
    files = prepare_sitl_files(replace(g2, runs=g2.runs + g1.runs), "out")    # relative: made absolute
    assert all(p.is_absolute() and p.exists() for p in (*files.maneuvers.values(), files.controller_path,
                                                         files.vehicle_path))
    cmd = fly_command(g1.runs[1], files, tmp_path / "r")
    i = cmd.index("--entry-offset")
    assert [float(v) for v in cmd[i + 1:i + 4]] == [0.6, 0.6, 0.6]
    j = cmd.index("--emulator-arg=--inertia-kg-m2")
    assert [float(a.split("=")[1]) for a in cmd[j + 1:j + 4]] == list(g1.runs[1].inertia_kg_m2)
    assert f"--emulator-arg=--seed={g1.runs[1].seed}" in cmd and "--world" in cmd and "--lockstep" in cmd
    assert not any("saturation" in a for a in cmd)
    sat = fly_command(g2.runs[2], files, tmp_path / "r")
    assert "--emulator-arg=--rotor-saturation-n=7.0" in sat and "--emulator-arg=--rotor-noise-sd-n=0.1" in sat
    assert not any("max-rotor-thrust" in a for a in sat)            # the daemon's 12 N scale is kept
    assert sat[4].endswith("barrel_roll_laps3.yaml") and cmd[4].endswith("barrel_roll.yaml")
    ctrl = load_controller(files.controller_path)
    assert ctrl.envelope.maneuver.max_position_error_m == 1.5
    assert ctrl.q_position == load_controller(g1.controller_path).q_position     # the paper's gains


@pytest.mark.slow          # 20 s; group 1 via sim runs in the unit tests; before each release
def test_one_group1_run_via_sitl_converges_before_the_loop(tmp_path):
    exp = paper_group1(0, samples=1)
    exp = replace(exp, runs=exp.runs[1:])                  # a drawn inertia, 0.6 m off in each axis
    camp = run_campaign(exp, "sitl", 1, tmp_path, "test command", progress=None)
    (out,) = camp.outcomes
    assert out.error is None, out.traceback
    m = out.metrics
    assert m["status"] == "completed" and m["extra"]["flight_result"] == "ok"
    assert m["start_distance_m"] == pytest.approx(0.85, abs=0.02)   # the regulator took over off the path
    assert m["converged"] and m["converged_at_s_m"] < 16.5 and camp.all_ok
    assert m["loop"]["transverse_error_m"]["max"] < 0.005            # 20 ms rotor lag: about 1.4 mm
    run_dir = tmp_path / "runs" / "001"
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["result"] == "ok"
    assert (run_dir / "flight.png").exists() and (run_dir / "fly.log").exists()
    assert not any((run_dir / f).exists() for f in FLIGHT_FILES)    # 17 MB a flight: not kept by default
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["via"] == "sitl" and res["sitl"]["world"] == "ideal" and res["summary"]["converged"] == 1


def test_a_gust_goes_to_the_emulator_as_a_force_window_from_the_maneuvers_start(tmp_path):
    from mavreg.experiments.definitions import gust
    from mavreg.experiments.via_sitl import SitlFiles
    exp = build_experiment("gust", 0, via="sitl")
    files = SitlFiles({1: exp.maneuver_path}, tmp_path / "c.yaml", exp.vehicle_path, maneuver_start_s=23.808)
    by = {r.label: r for r in exp.runs}
    cmd = fly_command(by["run-up 8 N, 12 N rotors, regulator"], files, tmp_path / "r")
    (wind,) = [a for a in cmd if a.startswith("--emulator-arg=--wind=")]
    assert wind == f"--emulator-arg=--wind=force:0.0,8.0,0.0@{23.808 + 6.311!r}:{23.808 + 7.311!r}"
    assert "--emulator-arg=--rotor-saturation-n=12.0" in cmd          # the vehicle file's own limit
    with pytest.raises(ValueError, match="reference flight"):
        fly_command(by["run-up 8 N, 12 N rotors, regulator"], replace(files, maneuver_start_s=None), tmp_path)
    assert {r.controller for r in exp.runs} == {"regulator"} and len(gust(0).runs) == 54


@pytest.mark.slow
def test_one_gust_run_via_sitl_strikes_on_the_run_up_at_speed(tmp_path):
    from mavreg.experiments.definitions import REGULATOR, gust
    exp = gust(0, forces_n=(8.0,), places=("run-up",), controllers=(REGULATOR,), saturations_n=(12.0,))
    camp = run_campaign(exp, "sitl", 1, tmp_path, "test command", progress=None)
    (out,) = camp.outcomes
    assert out.error is None, out.traceback
    m = out.metrics
    assert (tmp_path / "runs" / "reference" / "summary.json").exists()
    assert m["extra"]["gust_window_emulator_s"][1] - m["extra"]["gust_window_emulator_s"][0] == pytest.approx(1.0)
    tr = out.trace
    before = tr.t_s < 6.3
    assert tr.transverse_error_m[before].max() < 0.01                 # on the path until the gust
    speed = (tr.velocity_body_m_s ** 2).sum(axis=1) ** 0.5
    k = (tr.t_s > 6.3) & (tr.t_s < 6.5)
    assert speed[k].min() < 7.5 < 7.9 < speed[tr.t_s < 6.3][-1]       # the gust slows it down from 8 m/s
