"""``mavreg experiment robustness --via sim``: which cells fly, their world, and real flights."""
from __future__ import annotations

import json

import pytest

from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.cli.main import main
from mavreg.config.vehicle import load_vehicle
from mavreg.experiments.campaign import run_campaign
from mavreg.experiments.robustness import all_cells, robustness
from mavreg.experiments.robustness_sim import (REAL_COMMAND_DELAY_S, REAL_ESTIMATE_LATENCY_S,
                                               REAL_TELEMETRY_DELAY_S, robustness_via_sim, sim_world)

UNREPRESENTABLE_GROUPS = {"wind3", "wind6", "loss", "timesync"}


def test_the_design_model_flies_every_cell_but_wind_loss_and_timesync():
    exp = robustness_via_sim(0, 1, None)
    flown = {c.name for c in exp.cells}
    every = all_cells()
    assert flown == {c.name for c in every if c.group not in UNREPRESENTABLE_GROUPS}
    assert {"baseline", "thrust90", "gust-run-up", "gust-slow", "gust-loop", "rotors-8.5n", "rotors-7n", "mismatch",
            "rtt-000ms", "rtt-060ms", "estimator-x2", "maneuver-slalom"} <= flown
    skipped = dict(exp.skipped)
    assert set(skipped) == {c.name for c in every if c.group in UNREPRESENTABLE_GROUPS}
    assert "no drag" in skipped["wind6-from-090"] and "link protocol" in skipped["loss-5pct"]
    assert "TIMESYNC" in skipped["no-timesync"]
    assert exp.via == "sim" and len(exp.runs) == len(flown)


def test_seeds_are_those_of_the_sitl_campaign():
    sim = robustness_via_sim(3, 2, "baseline,mismatch,wind3")
    sitl = {r.label: r for r in robustness(3, 2, "baseline,mismatch").runs}
    assert [(r.label, r.seed, r.mismatch_seed) for r in sim.runs] == [
        (r.label, r.seed, r.mismatch_seed) for r in sitl.values()]


@pytest.mark.parametrize("cells, needle", [
    ("baseline,wind3-from-090", "wind3-from-090 (wind: the design model has no drag)"),
    ("no-timesync", "no-timesync (TIMESYNC: the design model has no link protocol)"),
    ("loss", "loss-5pct (message loss"),           # a group with nothing the design model flies
])
def test_unrepresentable_cells_named_are_refused_in_one_line(cells, needle, capsys, tmp_path):
    code = main(["experiment", "robustness", "--via", "sim", "--cells", cells, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and err.strip().count("\n") == 0
    assert "cannot fly via sim" in err and needle in err
    assert not (tmp_path / "o").exists()


def _spec(cell):
    return next(r for r in robustness(0, 1, cell).runs)


def test_each_cells_world_is_read_from_its_emulator_arguments():
    vehicle = load_vehicle(DEFAULT_VEHICLE)
    base = sim_world(_spec("baseline"), vehicle)
    assert base.measurement_delay_s == pytest.approx(REAL_TELEMETRY_DELAY_S + REAL_ESTIMATE_LATENCY_S)
    assert base.command_delay_s == REAL_COMMAND_DELAY_S and base.inertia_kg_m2 is None and not base.not_modelled
    rtt = sim_world(_spec("rtt-040ms"), vehicle)
    assert rtt.measurement_delay_s == pytest.approx(0.020 + REAL_ESTIMATE_LATENCY_S)
    assert rtt.command_delay_s == pytest.approx(0.020) and rtt.not_modelled == ("link jitter",)
    assert sim_world(_spec("estimator-x2"), vehicle).estimator_scale == 2.0
    assert sim_world(_spec("thrust90"), vehicle).thrust_scale == 0.9
    mm = _spec("mismatch")
    J = sim_world(mm, vehicle).inertia_kg_m2
    assert J == sim_world(mm, vehicle).inertia_kg_m2                      # from the mismatch seed alone
    for j, j0 in zip(J, vehicle.inertia_kg_m2):
        assert 0.7 * j0 <= j <= 1.3 * j0 and j != j0


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("robust-sim")
    exp = robustness_via_sim(0, 1, "baseline,gust-run-up,rotors-7n,wind6,loss")
    camp = run_campaign(exp, "sim", 1, out, "test", progress=None)
    return out, camp, {m["cell"]: m for m in camp.results["runs"]}


@pytest.mark.slow          # 34 s with the next test (one campaign); before each release (the same cells fly the defaults over SITL: tests/sitl/test_defaults_sitl.py)
def test_baseline_gust_and_7n_rotors_reach_the_end(campaign):
    _, camp, by = campaign
    assert set(by) == {"baseline", "gust-run-up", "rotors-7n"}
    for m in by.values():
        assert m["maneuver_completed"] and m["safety"] == "ok" and m["result"] == "ok", m["cause"]
        assert m["maneuver_duration_s"] > 20.0 and m["extra"]["world"]["command_delay_s"] == REAL_COMMAND_DELAY_S
        for key in ("lowest_altitude_m", "max_touchdown_speed_m_s", "ground_impact", "motors_stopped_in_air",
                    "flight_time_s", "first_bound"):
            assert m[key] is None, key                 # whole-flight numbers: via sitl only
    assert camp.all_ok
    # measured (seed 0): baseline 2.9 cm, attitude 2.4 deg
    assert by["baseline"]["maneuver_max_error_m"] < 0.05 and by["baseline"]["max_attitude_error_deg"] < 5.0
    # measured: 16.4 cm, 0.09 m/s. The disturbance observer takes the 1 s gust for a wind
    # (4 N, its cap) and keeps compensating it for about half a second after it ends; without
    # the observer the same flight stays within 4.2 cm.
    gust = by["gust-run-up"]
    assert gust["maneuver_max_error_m"] < 0.25 and gust["overspeed_m_s"] <= 0.3
    assert by["rotors-7n"]["loop_max_error_m"] <= 0.40          # measured 9.6 cm


@pytest.mark.slow          # the campaign above; before each release
def test_the_report_lists_the_skipped_cells_and_no_invented_numbers(campaign):
    out, _, _ = campaign
    res = json.loads((out / "results.json").read_text())
    assert res["via"] == "sim" and "14 ms late" in res["sim"]["world"]
    skipped = {k["cell"]: k["why"] for k in res["summary"]["skipped_cells"]}
    assert set(skipped) == {"wind6-from-000", "wind6-from-090", "wind6-from-180", "wind6-from-270", "loss-5pct"}
    md = (out / "results.md").read_text()
    assert "Not flown via sim: wind6-from-000 (wind: the design model has no drag)" in md
    assert "loss-5pct (message loss: the design model has no link protocol)" in md
    assert "| baseline | barrel roll" in md and "| — | — | — |" in md
    assert (out / "robustness_cells.png").stat().st_size > 0
