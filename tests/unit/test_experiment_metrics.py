"""Experiment metrics on known signals, and the truth trace against analytic errors."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mavreg.experiments.definitions import paper_group1
from mavreg.experiments.metrics import (CONVERGED_M, convergence_arc_length, laps_flown, run_metrics,
                                        saturated_share)
from mavreg.experiments.record import Flight, truth_trace
from mavreg.experiments.runner import plan_for
from mavreg.model.mixer import mixer_matrix
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.truth import true_errors


def test_convergence_of_an_exponential_decay_is_where_it_crosses_the_threshold():
    # e(s) = 0.85 exp(-(s + 0.6) / 0.1) crosses 1 cm at s* = -0.6 + 0.1 ln(85)
    s = np.linspace(-0.6, 20.0, 200_001)
    e = 0.85 * np.exp(-(s + 0.6) / 0.1)
    s_star = -0.6 + 0.1 * math.log(85.0)
    got = convergence_arc_length(s, e, CONVERGED_M, 16.5)
    assert got == pytest.approx(s_star, abs=2 * (s[1] - s[0]))


def test_a_later_excursion_above_the_threshold_moves_convergence_after_it():
    s = np.linspace(0.0, 20.0, 2001)                # 1 cm steps
    e = np.full_like(s, 0.001)
    e[s < 1.0] = 0.5
    e[(s >= 10.0) & (s < 12.0)] = 0.02              # a 2 cm excursion on the run-up
    assert convergence_arc_length(s, e, 0.01, 16.5) == pytest.approx(12.0)
    e[(s >= 16.0) & (s < 16.5)] = 0.02              # still above at the deadline: not converged
    assert convergence_arc_length(s, e, 0.01, 16.5) is None
    e[(s >= 16.0) & (s < 16.5)] = 0.001
    e[s >= 16.5] = 0.5                              # what happens after the deadline does not count
    assert convergence_arc_length(s, e, 0.01, 16.5) == pytest.approx(12.0)


def test_convergence_edge_cases():
    s = np.linspace(0.0, 20.0, 201)
    assert convergence_arc_length(s, np.zeros_like(s), 0.01, 16.5) == 0.0          # converged from the start
    assert convergence_arc_length(s[:100], np.zeros(100), 0.01, 16.5) is None      # never reaches the loop
    e = np.zeros_like(s)
    e[50] = np.nan                                                                  # NaN is not converged
    assert convergence_arc_length(s, e, 0.01, 16.5) == pytest.approx(s[51])
    # time order matters, not s order: going back past the deadline's s first counts
    s_back = np.array([0.0, 5.0, 17.0, 3.0, 18.0])
    assert convergence_arc_length(s_back, np.array([0.5, 0.0, 0.0, 0.5, 0.0]), 0.01, 16.5) == 5.0
    with pytest.raises(ValueError):
        convergence_arc_length(s, np.zeros(3), 0.01, 16.5)


def test_saturated_share_counts_samples_with_any_rotor_at_the_limit():
    f = np.full((1000, 4), 5.0)
    f[:100, 2] = 7.0                        # 10 % with rotor 3 at the limit
    f[100:150, :] = 7.0                     # 5 % with all four
    f[150:160, 0] = 7.0 * (1 - 1e-6)        # just under: not saturated
    assert saturated_share(f, 7.0) == pytest.approx(0.15)
    assert saturated_share(f, 7.0, every_rotor=True) == pytest.approx(0.05)
    assert saturated_share(f, None) == 0.0
    assert saturated_share(np.zeros((0, 4)), 7.0) == 0.0


def test_laps_flown_from_the_largest_arc_length():
    assert laps_flown([0.0, 10.0, 45.0], 20.0, 40.0, 3) == 3.0
    assert laps_flown([0.0, 30.0], 20.0, 40.0, 3) == pytest.approx(1.5)
    assert laps_flown([0.0, 15.0], 20.0, 40.0, 3) == 0.0


@pytest.fixture(scope="module")
def plan():
    exp = paper_group1(0, samples=0)
    return plan_for(exp.maneuver_path, exp.vehicle_path, exp.controller_path, 1)


def _flight_on(plan, s, offset_normal_m=0.0, tilt_rad=0.0, sat=None, applied=None):
    """True samples on the nominal at ``s``, moved along the path's normal and tilted about
    the body x axis by known amounts."""
    pos, rot, vel = [], [], []
    for si in s:
        pt = plan.path.point(si)
        x = plan.nominal_state(si)
        pos.append(pt.position + offset_normal_m * pt.frame[:, 1])
        R = rpy_to_matrix(*x[3:6]) @ rpy_to_matrix(tilt_rad, 0.0, 0.0)
        rot.append(R)
        vel.append(rpy_to_matrix(*x[3:6]) @ x[6:9])
    k = len(s)
    M = mixer_matrix(plan.vehicle.arm_length_m, plan.vehicle.drag_torque_ratio_m)
    cmd = np.tile(np.linalg.solve(M, plan.u[0]), (k, 1))
    return Flight(np.arange(k) * 0.01, np.array(pos), np.array(rot), np.array(vel), cmd,
                  cmd if applied is None else applied, "completed", "", True, sat, {})


def test_truth_trace_measures_a_known_offset_and_tilt(plan):
    s = np.linspace(0.5, plan.length_m - 0.5, 400)
    on = truth_trace(plan, _flight_on(plan, s))
    assert np.max(on.transverse_error_m) < 1e-6 and np.max(on.attitude_error_deg) < 1e-4
    np.testing.assert_allclose(on.s_m, s, atol=1e-6)
    off = truth_trace(plan, _flight_on(plan, s, offset_normal_m=0.05, tilt_rad=math.radians(10.0)))
    np.testing.assert_allclose(off.transverse_error_m, 0.05, atol=1e-6)
    np.testing.assert_allclose(off.attitude_error_deg, 10.0, atol=1e-6)
    # the body velocity of the nominal is the plan's, and the commanded wrench eq 34 of the rotors
    np.testing.assert_allclose(on.velocity_body_m_s, np.array([plan.nominal_state(x)[6:9] for x in s]),
                               atol=1e-9)
    np.testing.assert_allclose(on.wrench_command[0], plan.u[0], atol=1e-9)


def test_run_metrics_agree_with_mavreg_sim_truth_on_the_same_samples(plan):
    s = np.linspace(0.5, plan.length_m - 0.5, 600)
    fl = _flight_on(plan, s, offset_normal_m=0.02, tilt_rad=math.radians(3.0))
    tr = truth_trace(plan, fl)
    exp = paper_group1(0, samples=0)
    m = run_metrics(plan, tr, fl, exp.runs[0], exp.kind)
    ref = true_errors(plan, fl.position_m, fl.rotation)["segments"]["loop"]
    assert m["loop"]["transverse_error_m"]["max"] == pytest.approx(ref["max_m"], rel=1e-9)
    assert m["loop"]["transverse_error_m"]["rms"] == pytest.approx(ref["rms_m"], rel=1e-9)
    assert m["loop"]["attitude_error_deg"]["max"] == pytest.approx(ref["max_deg"], rel=1e-9)
    assert not m["converged"] and not m["ok"]       # 2 cm off all along: never within 1 cm
    assert m["laps_flown"] == 1.0 and m["stable"]   # flown to the end, within 10 cm of the path there
    far = _flight_on(plan, s, offset_normal_m=0.2)
    assert not run_metrics(plan, truth_trace(plan, far), far, exp.runs[0], exp.kind)["stable"]
