"""Experiment definitions: runs fixed by the seed, the inertia draws' statistics."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.vehicle import load_vehicle
from mavreg.experiments.definitions import (CONVERGENCE, MIN_INERTIA_KG_M2, PAPER_INERTIA_SD_KG_M2, SATURATION,
                                            build_experiment, draw_inertia, paper_group1, paper_group2, run_seed)
from mavreg.cli.common import DEFAULT_VEHICLE

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
    with pytest.raises(ValueError, match="paper-group1, paper-group2"):
        build_experiment("gust")
    assert build_experiment("paper-group2", 5) == paper_group2(5)
