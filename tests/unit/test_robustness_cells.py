"""The robustness experiment's matrix: cells, seeds, --flights, --cells, and what each flight runs."""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from mavreg.config.paths import REAL_CONTROLLER, maneuver_files
from mavreg.cli.main import main
from mavreg.experiments.definitions import GUST_PLACES, gust, run_seed
from mavreg.experiments.robustness import (DEFAULT_FLIGHTS, MISMATCH_STREAM, ROBUSTNESS, all_cells, robustness,
                                           select_cells)
from mavreg.experiments.via_sitl import fly_command, prepare_sitl_files


def _by_name(exp):
    return {c.name: c for c in exp.cells}


def test_the_matrix_is_the_documented_one():
    cells = all_cells()
    groups = {}
    for c in cells:
        groups.setdefault(c.group, []).append(c.name)
    assert list(groups) == ["baseline", "wind3", "wind6", "thrust90", "gust", "rotors", "mismatch", "delay",
                            "loss", "timesync", "estimator", "maneuvers"]
    assert cells[0].name == "baseline" and cells[0].emulator_args == () and cells[0].saturation_n is None
    by = {c.name: c for c in cells}
    assert [by[n].emulator_args for n in groups["wind3"]] == [
        ("--wind-speed-m-s=3", f"--wind-from-deg={d}") for d in range(0, 360, 45)]
    assert [by[n].emulator_args[1] for n in groups["wind6"]] == [f"--wind-from-deg={d}" for d in (0, 90, 180, 270)]
    assert by["thrust90"].emulator_args == ("--thrust-scale=0.9",)
    assert [by[n].gust_place for n in groups["gust"]] == list(GUST_PLACES)
    assert [by[n].saturation_n for n in groups["rotors"]] == [8.5, 7.0]
    assert by["mismatch"].mismatch and by["mismatch"].emulator_args == ()
    assert by["rtt-000ms"].emulator_args == ("--telemetry-delay-s=0", "--telemetry-jitter-s=0",
                                             "--command-delay-s=0", "--command-jitter-s=0")
    assert by["rtt-060ms"].emulator_args == ("--telemetry-delay-s=0.03", "--telemetry-jitter-s=0.005",
                                             "--command-delay-s=0.03", "--command-jitter-s=0.005")
    assert len(groups["delay"]) == 4
    assert by["loss-5pct"].emulator_args == ("--loss=0.05",)
    assert by["no-timesync"].emulator_args == ("--no-timesync",)
    assert by["estimator-x2"].emulator_args == ("--estimator-scale=2",)
    files = sorted(p.stem for p in maneuver_files() if p.stem != "barrel_roll")
    assert groups["maneuvers"] == [f"maneuver-{f}" for f in files] and files
    assert all(c.maneuver_path.name == "barrel_roll.yaml" for c in cells if c.group != "maneuvers")


def test_every_seed_is_fixed_before_flying_and_shared_across_cells():
    exp = robustness(7, 3)
    again = robustness(7, 3)
    assert exp.runs == again.runs and exp.kind == ROBUSTNESS and exp.controller_path == REAL_CONTROLLER
    assert [r.index for r in exp.runs] == list(range(len(exp.runs)))
    for r in exp.runs:
        k = int(r.label.split("#")[1])
        assert r.seed == run_seed(7, k)                # flight k of every cell: the same noise
        if r.cell == "mismatch":
            assert r.mismatch_seed == run_seed(7, MISMATCH_STREAM + k)
            assert r.emulator_args[-1] == f"--mismatch-seed={r.mismatch_seed}"
        else:
            assert r.mismatch_seed is None and not any("mismatch" in a for a in r.emulator_args)
    draws = [r.mismatch_seed for r in exp.runs if r.cell == "mismatch"]
    assert len(set(draws)) == 3 and not set(draws) & {r.seed for r in exp.runs}
    assert {r.seed for r in robustness(8, 3).runs}.isdisjoint({r.seed for r in exp.runs})
    assert all(r.rotor_noise_sd_n is None and r.laps is None for r in exp.runs)    # the files' own


def test_flights_is_the_number_of_seeds_of_every_cell():
    exp = robustness(0)
    assert exp.flights == DEFAULT_FLIGHTS and len(exp.runs) == DEFAULT_FLIGHTS * len(all_cells())
    hundred = robustness(0, 100, "mismatch")
    assert len(hundred.runs) == 100 and {r.cell for r in hundred.runs} == {"mismatch"}
    assert len({r.mismatch_seed for r in hundred.runs}) == 100
    for bad in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="--flights"):
            robustness(0, bad)


def test_the_cell_filter_takes_groups_and_cell_names():
    assert [c.name for c in select_cells("mismatch,gust")] == ["gust-run-up", "gust-slow", "gust-loop", "mismatch"]
    assert [c.name for c in select_cells(" wind3-from-090 ,baseline")] == ["baseline", "wind3-from-090"]
    assert select_cells(None) == select_cells("all") == all_cells()
    with pytest.raises(ValueError, match="unknown cell or group 'windy'"):
        select_cells("wind3,windy")
    with pytest.raises(ValueError, match="names no cell"):
        select_cells(" , ")


def test_the_gust_cells_are_the_gust_experiments_8_n_at_its_places():
    exp = robustness(0, 1, "gust")
    ref = {r.group: r for r in gust(0, forces_n=(8.0,), saturations_n=(None,), controllers=("regulator",)).runs}
    for r in exp.runs:
        place = r.cell.removeprefix("gust-")
        assert r.gust_force_n == ref[place].gust_force_n and r.gust_window_s == ref[place].gust_window_s


def test_each_flight_flies_the_default_controller_on_the_realistic_world_with_its_cells_arguments(tmp_path):
    exp = robustness(0, 1, "baseline,rotors,no-timesync,mismatch,maneuver-slalom,rtt-040ms")
    files = prepare_sitl_files(exp, tmp_path)
    assert files.controller_path == REAL_CONTROLLER.resolve() and files.world == "realistic"
    assert not list(tmp_path.glob("controller_experiment*"))          # the envelope is not widened
    by = {r.cell: r for r in exp.runs}
    base = fly_command(by["baseline"], files, tmp_path / "r")
    assert base[base.index("--world") + 1] == "realistic"
    assert base[base.index("--controller") + 1] == str(REAL_CONTROLLER.resolve())
    assert base[4].endswith("barrel_roll.yaml") and not any("noise" in a or "--wind" in a for a in base)
    assert f"--emulator-arg=--seed={by['baseline'].seed}" in base
    seven = fly_command(by["rotors-7n"], files, tmp_path / "r")
    assert "--emulator-arg=--rotor-saturation-n=7.0" in seven
    told = yaml.safe_load(Path(seven[seven.index("--controller") + 1]).read_text())
    default = yaml.safe_load(REAL_CONTROLLER.read_text())
    assert told["allocation"]["max_rotor_thrust_n"] == 7.0
    assert told.get("envelope") == default.get("envelope") and told["q_position"] == default["q_position"]
    assert "--emulator-arg=--no-timesync" in fly_command(by["no-timesync"], files, tmp_path / "r")
    mm = fly_command(by["mismatch"], files, tmp_path / "r")
    assert f"--emulator-arg=--mismatch-seed={by['mismatch'].mismatch_seed}" in mm
    assert fly_command(by["maneuver-slalom"], files, tmp_path / "r")[4].endswith("slalom.yaml")
    rtt = fly_command(by["rtt-040ms"], files, tmp_path / "r")
    assert "--emulator-arg=--telemetry-delay-s=0.02" in rtt and "--emulator-arg=--command-jitter-s=0.005" in rtt


def test_a_gust_window_starts_at_its_own_seeds_reference(tmp_path):
    from dataclasses import replace
    exp = robustness(0, 2, "gust-run-up")
    files = replace(prepare_sitl_files(replace(exp, runs=()), tmp_path),
                    starts_by_seed=((exp.runs[0].seed, 20.0), (exp.runs[1].seed, 21.5)))
    for r, t0 in zip(exp.runs, (20.0, 21.5)):
        (wind,) = [a for a in fly_command(r, files, tmp_path) if a.startswith("--emulator-arg=--wind=")]
        a, b = (t0 + w for w in r.gust_window_s)
        assert wind.endswith(f"@{a!r}:{b!r}") and "force:0.0,8.0,0.0" in wind


@pytest.mark.parametrize("argv, needle", [
    (["--via", "sim", "--cells", "wind3-from-090"], "cannot fly via sim: wind3-from-090"),
    (["--flights", "0"], "--flights must be at least 1, got 0"),
    (["--flights", "many"], "--flights must be a whole number"),
    (["--cells", "nowhere"], "unknown cell or group 'nowhere'"),
])
def test_bad_input_is_one_line_and_exit_2(argv, needle, capsys, tmp_path):
    code = main(["experiment", "robustness", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.strip().count("\n") == 0 and needle in err
    assert not (tmp_path / "out").exists()


def test_flights_and_cells_belong_to_robustness_alone(capsys, tmp_path):
    assert main(["experiment", "gust", "--cells", "gust", "--out", str(tmp_path / "o")]) == 2
    assert "apply only to the robustness experiment" in capsys.readouterr().err


def test_one_reference_flight_per_noise_seed_gives_the_gust_windows(tmp_path, monkeypatch):
    import mavreg.experiments.via_sitl as via_sitl
    exp = robustness(0, 3, "gust,baseline")
    flown = []

    def fake_reference(run, files, run_dir):
        flown.append((run.seed, run_dir.name))
        return 20.0 + run.index                        # any start, told apart by the run
    monkeypatch.setattr(via_sitl, "_reference_start", fake_reference)
    files = prepare_sitl_files(exp, tmp_path, jobs=2)
    seeds = [run_seed(0, k) for k in range(3)]
    assert sorted(flown) == sorted((s, f"reference-{s}") for s in seeds)      # 3, not 9
    for r in exp.runs:
        if r.gust_force_n is not None:
            first = next(g for g in exp.runs if g.gust_force_n is not None and g.seed == r.seed)
            assert files.start_for(r.seed) == 20.0 + first.index


def test_a_failed_reference_makes_its_seeds_gust_runs_errors_and_no_others(tmp_path, monkeypatch):
    import mavreg.experiments.via_sitl as via_sitl
    exp = robustness(0, 2, "gust-slow")
    bad = exp.runs[1].seed

    def fake_reference(run, files, run_dir):
        if run.seed == bad:
            raise ValueError("the gust-free reference flight never began its maneuver: gate_position")
        return 22.0
    monkeypatch.setattr(via_sitl, "_reference_start", fake_reference)
    files = prepare_sitl_files(exp, tmp_path, jobs=2)
    assert files.start_for(exp.runs[0].seed) == 22.0
    fly_command(exp.runs[0], files, tmp_path)
    with pytest.raises(ValueError, match=f"reference flight of seed {bad} failed: .*gate_position"):
        fly_command(exp.runs[1], files, tmp_path)
