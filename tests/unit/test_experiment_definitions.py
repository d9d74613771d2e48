"""Experiment definitions: runs fixed by the seed, the inertia draws' statistics."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.vehicle import load_vehicle
from mavreg.experiments.definitions import (BARREL_ROLL, CONTROLLERS, CONVERGENCE, DISTURBANCE, GUST_DURATION_S,
                                            GUST_FORCES_N, GUST_PLACES, LAG_LEADS_M, LAG_START_S_M,
                                            MIN_INERTIA_KG_M2, PAPER_INERTIA_SD_KG_M2, REGULATOR, ROTOR_LIMITS_N,
                                            SATURATION, build_experiment, draw_inertia, gust, lag, nominal_clock,
                                            paper_group1, paper_group2, run_seed)
from mavreg.config.paths import DEFAULT_VEHICLE

J0 = np.array(load_vehicle(DEFAULT_VEHICLE).inertia_kg_m2)


def test_group1_is_the_papers_26_runs_and_the_same_seed_gives_the_same_runs():
    a, b = paper_group1(7), paper_group1(7)
    assert a == b and a.kind == CONVERGENCE and len(a.runs) == 26
    assert a.runs[0].inertia_kg_m2 is None                  # one run on the nominal inertia
    assert all(r.offset_m == (0.6, 0.6, 0.6) for r in a.runs)
    assert all(r.rotor_noise_sd_n == 0.0 and r.saturation_n is None and r.laps == 1 for r in a.runs)
    assert [r.index for r in a.runs] == list(range(26))
    c = paper_group1(8)
    assert [r.inertia_kg_m2 for r in c.runs[1:]] != [r.inertia_kg_m2 for r in a.runs[1:]]
    # fewer samples are a prefix of the same draw: a small campaign flies the big one's first runs
    assert paper_group1(7, samples=3).runs == a.runs[:4]


def test_group2_cases_share_one_noise_seed_and_differ_only_by_saturation():
    e = paper_group2(3)
    assert e.kind == SATURATION
    assert [r.saturation_n for r in e.runs] == [None, 8.5, 7.0]
    assert {r.seed for r in e.runs} == {run_seed(3, 0)}
    assert all(r.rotor_noise_sd_n == 0.1 and r.laps == 3 and r.offset_m == (0.0, 0.0, 0.0)
               and r.inertia_kg_m2 is None for r in e.runs)
    assert paper_group2(4).runs[0].seed != e.runs[0].seed
    with pytest.raises(ValueError, match="laps"):
        paper_group2(0, laps=0)


def test_run_seeds_are_distinct_and_fit_31_bits():
    seeds = [run_seed(0, i) for i in range(1000)] + [run_seed(1, i) for i in range(1000)]
    assert len(set(seeds)) == len(seeds)
    assert 0 <= min(seeds) and max(seeds) < 2 ** 31


def test_inertia_draws_have_the_papers_sd_mean_and_independence():
    # 60 000 fixed-seed draws per axis: the sample SD's own SD is sigma / sqrt(2n) = 0.29 %
    # of sigma, so a 2 % tolerance is 7 of those; the mean's is 0.41 % of sigma (tolerance 2 %).
    # The draw is deterministic: these cannot flake, and a wrong SD (e.g. 0.0102) fails.
    J = draw_inertia(J0, 60_000, seed=12345)
    assert J.shape == (60_000, 3)
    sd = J.std(axis=0, ddof=1)
    assert np.all(np.abs(sd / PAPER_INERTIA_SD_KG_M2 - 1.0) < 0.02), sd
    assert np.all(np.abs(J.mean(axis=0) - J0) < 0.02 * PAPER_INERTIA_SD_KG_M2)
    corr = np.corrcoef(J.T)
    assert np.all(np.abs(corr[np.triu_indices(3, 1)]) < 0.02)       # drawn independently
    # about 95 % within 2 SD, as the paper says (0.9545; binomial SD 0.085 %)
    within = np.mean(np.abs(J - J0) < 2 * PAPER_INERTIA_SD_KG_M2)
    assert abs(within - 0.9545) < 0.005


def test_a_draw_below_the_floor_is_drawn_again():
    J = draw_inertia([0.002, 0.002, 0.002], 2000, seed=1)   # 0.3 SD above the floor: many redraws
    assert J.min() >= MIN_INERTIA_KG_M2
    np.testing.assert_array_equal(J, draw_inertia([0.002, 0.002, 0.002], 2000, seed=1))


def test_unknown_experiment_names_the_known_ones():
    with pytest.raises(ValueError, match="paper-group1, paper-group2, gust, lag"):
        build_experiment("wind")
    assert build_experiment("paper-group2", 5) == paper_group2(5)


def test_gust_cases_are_every_place_force_rotor_limit_and_controller():
    e = gust(3)
    assert e == gust(3) and e.kind == DISTURBANCE and len(e.runs) == 3 * 3 * 2 * 3
    assert [r.index for r in e.runs] == list(range(54))
    assert len({r.seed for r in e.runs}) == 54 and gust(4).runs[0].seed != e.runs[0].seed
    cells = {(r.group, r.case, r.saturation_n, r.controller) for r in e.runs}
    assert cells == {(g, f"{F:g} N", sat, c) for g in GUST_PLACES for F in GUST_FORCES_N
                     for sat in ROTOR_LIMITS_N for c in CONTROLLERS}
    for r in e.runs:
        assert r.start_s_m == 0.0 and r.reference_lead_m == 0.0 and r.rotor_noise_sd_n == 0.0
        assert r.gust_window_s[1] - r.gust_window_s[0] == pytest.approx(GUST_DURATION_S)
        assert np.linalg.norm(r.gust_force_n) == pytest.approx(float(r.case.split()[0]))
    t_of_s, tangent = nominal_clock(BARREL_ROLL)
    by = {(r.group, r.case): r for r in e.runs}
    # on the run-up the path flies west: the gust pushes east, when the nominal is at s = 11 m
    assert by[("run-up", "8 N")].gust_force_n == (0.0, 8.0, 0.0)
    assert by[("run-up", "8 N")].gust_window_s[0] == pytest.approx(t_of_s(11.0), abs=5e-4)
    assert t_of_s(11.0) == pytest.approx(6.311, abs=1e-3) and t_of_s(2.0) == pytest.approx(3.653, abs=1e-3)
    # in the loop it is held in the direction against the tangent where the circle begins
    np.testing.assert_allclose(by[("loop", "10 N")].gust_force_n, -10.0 * tangent(19.5), atol=1e-9)
    assert by[("loop", "10 N")].gust_force_n[2] > 5.0            # the loop climbs: the gust pushes down


def test_lag_cases_start_on_the_run_up_with_the_reference_ahead():
    e = lag(1)
    assert e.kind == DISTURBANCE and len(e.runs) == 3 * 2 * 3
    assert {r.reference_lead_m for r in e.runs} == set(LAG_LEADS_M)
    assert all(r.start_s_m == LAG_START_S_M and r.gust_force_n is None for r in e.runs)
    assert [r.controller for r in e.runs[:3]] == list(CONTROLLERS)
    with pytest.raises(ValueError, match="controllers"):
        lag(0, controllers=("pid",))


def test_via_sitl_only_the_regulator_flies_the_gust_and_lag_does_not_fly():
    e = build_experiment("gust", 0, via="sitl")
    assert len(e.runs) == 9 and {r.controller for r in e.runs} == {REGULATOR}
    assert {r.saturation_n for r in e.runs} == {12.0}
    assert [r.gust_force_n for r in e.runs] == [r.gust_force_n for r in gust(0).runs
                                                if r.controller == REGULATOR and r.saturation_n == 12.0]
    with pytest.raises(ValueError, match="design model"):
        build_experiment("lag", 0, via="sitl")
