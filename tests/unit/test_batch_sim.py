"""The batch simulator against the sequential one: every run's record agrees to 1e-9.

The reference is :func:`mavreg.sim.maneuver_run.fly_on_design_model` (what ``mavreg
experiment --via sim`` flies, one run at a time); the batch is
:func:`mavreg.sim.batch.fly_batch`, on both of its paths: compiled (numba; skipped without
it) and numpy (the pure path).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, REAL_CONTROLLER, maneuver_file
from mavreg.accel import ACCELERATED
from mavreg.config.controller import load_controller
from mavreg.control.estimation.lag_in_effect import RotorLagInEffect
from mavreg.config.maneuver import load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.experiments.definitions import paper_group1
from mavreg.maneuver.plan import plan_spec
from mavreg.planning.plan_io import plan_file
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.sim.batch import BatchRun, fly_batch
from mavreg.sim.closed_loop import SimOptions, simulate
from mavreg.sim.maneuver_run import fly_on_design_model

PATHS = [pytest.param(True, id="compiled", marks=pytest.mark.skipif(not ACCELERATED, reason="numba not in use"))]
"""The compiled batch against the sequential simulator (its pure path is that simulator)."""
VEHICLE = load_vehicle(DEFAULT_VEHICLE)
PAPER = load_controller(PAPER_CONTROLLER)
BARREL = maneuver_file("barrel_roll")

SHORT = """\
kind: maneuver
version: 1
name: short
start: {position_m: [0, 0, -3], heading_deg: 30}
segments:
  - name: a
    line: {length_m: 3.0}
  - name: b
    arc: {radius_m: 3.0, angle_deg: 45, bend_deg: 90}
    blend_m: 2.0
  - name: c
    line: {length_m: 3.0}
    blend_m: 2.0
speed: {initial_m_s: 3.0}
"""


def as_batch(spec) -> BatchRun:
    return BatchRun(spec.offset_m, spec.inertia_kg_m2, spec.rotor_noise_sd_n, spec.saturation_n, spec.seed)


def sequential(plan, run: BatchRun, extra_time_s: float, **regulator):
    return fly_on_design_model(plan, offset_m=run.offset_m, inertia_kg_m2=run.inertia_kg_m2,
                               rotor_noise_sd_n=run.rotor_noise_sd_n, saturation_n=run.saturation_n,
                               seed=run.seed, extra_time_s=extra_time_s, **regulator).result


def assert_agree(seq, bat, tol=1e-9):
    assert (bat.status, bat.reason, bat.controller_calls) == (seq.status, seq.reason, seq.controller_calls)
    np.testing.assert_array_equal(bat.t, seq.t)
    np.testing.assert_allclose(bat.x, seq.x, rtol=0, atol=tol)
    np.testing.assert_allclose(bat.rotor_command_n, seq.rotor_command_n, rtol=0, atol=tol)
    np.testing.assert_allclose(bat.rotor_applied_n, seq.rotor_applied_n, rtol=0, atol=tol)


@pytest.fixture(scope="module")
def barrel():
    return plan_file(BARREL, VEHICLE, PAPER)


@pytest.mark.parametrize("compiled", PATHS)
def test_group1_runs_agree_with_the_sequential_simulator_on_the_start_of_the_barrel_roll(barrel, compiled):
    """The first 1.5 s (the 0.6 m start offset being taken out) of three group 1 runs: the
    nominal inertia and two drawn ones."""
    runs = [as_batch(r) for r in paper_group1(seed=0).runs[:3]]
    extra = 1.5 - barrel.duration_s
    for run, bat in zip(runs, fly_batch(barrel, runs, extra_time_s=extra, compiled=compiled)):
        assert bat.status.value == "timeout" and len(bat.t) == 1501
        assert_agree(sequential(barrel, run, extra), bat)


@pytest.mark.parametrize("compiled", PATHS)
def test_runs_that_end_at_different_times_noise_saturation_and_a_failed_start_agree(compiled):
    """A short maneuver flown to its end from different offsets and inertias (the runs
    complete at different steps), with rotor noise from a seed and with saturation, and a
    run that starts beyond the position bound (diverged at t = 0)."""
    plan = plan_spec(load_maneuver_text(SHORT, "short.yaml"), VEHICLE, PAPER)
    runs = [BatchRun((0.2, 0.1, -0.1)), BatchRun((0.0, -0.3, 0.2), (0.02, 0.015, 0.03)),
            BatchRun((0.1, 0.1, 0.1), None, 0.1, 7.0, 11), BatchRun((0.0, 0.0, 0.0), None, 0.1, None, 11),
            BatchRun((2e4, 0.0, 0.0))]
    batch = fly_batch(plan, runs, extra_time_s=1.0, compiled=compiled)
    ends = {len(b.t) for b in batch[:4]}
    assert len(ends) > 1 and all(b.status.value == "completed" for b in batch[:4])
    for run, bat in zip(runs[:4], batch):
        assert_agree(sequential(plan, run, 1.0), bat)
    x0 = plan.entry_state + np.r_[2e4, np.zeros(11)]
    ref = simulate(QuadrotorModel.from_vehicle(VEHICLE), Mixer.from_vehicle(VEHICLE),
                   lambda t, x: np.zeros(4), SimOptions(initial_state=x0))
    assert ref.status.value == "diverged" and ref.reason.startswith("initial state: position")
    assert_agree(ref, batch[4])


@pytest.mark.parametrize("compiled", PATHS)
def test_the_governed_controller_with_torques_first_allocation_agrees(compiled):
    """``paper_governed.yaml`` (the speed governor, torques-first allocation told a 7 N limit),
    as group 2 flies it: rotor noise, 7 N rotors, and a start 0.4 m behind and below, which
    the governor answers. The paper's regulator flown on the same runs differs by more than
    a millimetre (the negative control)."""
    from mavreg.config.paths import PAPER_GOVERNED_CONTROLLER
    from mavreg.config.regulation import told_rotor_limit
    governed = load_controller(PAPER_GOVERNED_CONTROLLER)
    assert governed.speed_governor.enabled and governed.allocation.method == "torques_first"
    plan = plan_spec(load_maneuver_text(SHORT, "short.yaml"), VEHICLE, governed)
    regulator = {"allocation": told_rotor_limit(governed.allocation, 7.0),
                 "speed_governor": governed.speed_governor}
    runs = [BatchRun((-0.4, 0.0, 0.3), None, 0.1, 7.0, 5), BatchRun((0.0, 0.2, 0.0), (0.02, 0.02, 0.03))]
    batch = fly_batch(plan, runs, extra_time_s=1.0, compiled=compiled, **regulator)
    for run, bat in zip(runs, batch):
        assert bat.status.value == "completed"
        assert_agree(sequential(plan, run, 1.0, **regulator), bat)
    paper = fly_batch(plan, runs[:1], extra_time_s=1.0, compiled=compiled)[0]
    k = min(len(paper.x), len(batch[0].x))
    assert np.abs(paper.x[:k, :3] - batch[0].x[:k, :3]).max() > 1e-3


@pytest.mark.parametrize("compiled", PATHS)
def test_a_controller_that_returns_nan_ends_the_run_as_simulate_ends_it(compiled):
    """Gains that are NaN past s = 3.5 m: the command there is not finite; the run ends at
    that step with the previous applied forces in its last row, the other runs go on."""
    plan = plan_spec(load_maneuver_text(SHORT, "short.yaml"), VEHICLE, PAPER)
    K = plan.K.copy()
    K[plan.s > 3.5] = np.nan
    broken = dataclasses.replace(plan, K=K)
    runs = [BatchRun((0.1, 0.0, 0.0)), BatchRun((0.0, 0.2, 0.0), (0.02, 0.02, 0.03))]
    batch = fly_batch(broken, runs, extra_time_s=1.0, compiled=compiled)
    model, mixer = QuadrotorModel.from_vehicle(VEHICLE), Mixer.from_vehicle(VEHICLE)
    for run, bat in zip(runs, batch):
        reg = ManeuverRegulator(broken, VEHICLE, control_period_s=1e-3, rotor_lag=RotorLagInEffect(0.0))
        x0 = broken.entry_state + np.r_[run.offset_m, np.zeros(9)]
        reg.reset(x0)
        ref = simulate(model, mixer, lambda t, x: reg.step(x).rotor_forces_n,
                       SimOptions(initial_state=x0, max_duration_s=broken.duration_s + 1.0,
                                  inertia_kg_m2=run.inertia_kg_m2))
        assert ref.reason.startswith("controller returned non-finite rotor forces")
        assert_agree(ref, bat)


@pytest.mark.parametrize("compiled", PATHS)
def test_control_rate_below_the_physics_rate_holds_the_command(barrel, compiled):
    """500 Hz control on 1 kHz physics: zero-order hold and the half-period feedforward lead."""
    run = BatchRun((0.3, -0.2, 0.1), None, 0.1, None, 3)
    extra = 0.5 - barrel.duration_s
    bat = fly_batch(barrel, [run], control_rate_hz=500.0, extra_time_s=extra, compiled=compiled)[0]
    seq = fly_on_design_model(barrel, offset_m=run.offset_m, rotor_noise_sd_n=0.1, seed=3, control_rate_hz=500.0,
                              extra_time_s=extra).result
    assert bat.controller_calls == 250
    assert_agree(seq, bat)


def test_lag_aware_gains_and_odd_control_rates_are_refused(barrel):
    with pytest.raises(ValueError, match="whole number"):
        fly_batch(barrel, [BatchRun()], control_rate_hz=300.0)
    with pytest.raises(ValueError, match="at least one run"):
        fly_batch(barrel, [])
    lagged = load_controller(REAL_CONTROLLER)
    with pytest.raises(ValueError, match="paper's design"):
        fly_batch(plan_file(BARREL, VEHICLE, lagged), [BatchRun()])
    if not ACCELERATED:
        with pytest.raises(ValueError, match="no compiled batch"):
            fly_batch(barrel, [BatchRun()], compiled=True)


def test_the_pure_path_is_the_sequential_simulator(barrel):
    """compiled=False (and no numba, or MAVREG_PURE=1) flies each run by the sequential
    simulator: the same records exactly."""
    run = BatchRun((0.1, -0.1, 0.05), (0.02, 0.015, 0.03), 0.1, 9.0, 5)
    extra = 0.3 - barrel.duration_s
    bat = fly_batch(barrel, [run], extra_time_s=extra, compiled=False)[0]
    assert_agree(sequential(barrel, run, extra), bat, tol=0.0)


@pytest.mark.slow
def test_all_of_group1_agrees_over_the_whole_maneuver(barrel):
    """The 26 runs of the paper's group 1, the full barrel roll at 1 kHz (about 4 minutes
    of the sequential simulator)."""
    runs = [as_batch(r) for r in paper_group1(seed=0).runs]
    batches = [fly_batch(barrel, runs, compiled=c) for c in ((True, False) if ACCELERATED else (False,))]
    for i, run in enumerate(runs):
        seq = sequential(barrel, run, 5.0)
        for batch in batches:
            assert batch[i].status.value == "completed"
            assert_agree(seq, batch[i])


@pytest.mark.slow
def test_a_run_that_falls_diverges_at_the_same_step(barrel):
    """Rotors saturated at 0.3 N cannot hold the vehicle: on the slow start of the run-up it
    falls until the speed bound (50 m/s, about 6 s)."""
    run = BatchRun((0.0, 0.0, 0.0), None, 0.0, 0.3, 0)
    extra = 8.0 - barrel.duration_s
    seq = sequential(barrel, run, extra)
    for compiled in (True, False) if ACCELERATED else (False,):
        bat = fly_batch(barrel, [run], extra_time_s=extra, compiled=compiled)[0]
        assert bat.status.value == "diverged" and bat.reason.startswith("speed")
        assert_agree(seq, bat)
