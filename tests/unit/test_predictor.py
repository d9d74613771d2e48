"""The state predictor against the plant it models, with a known delay and rotor lag."""
import dataclasses
import math

import numpy as np
import pytest

from mavreg.config.vehicle import G
from mavreg.control.estimation.predictor import StatePredictor
from mavreg.model.mixer import Mixer
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.model.rotation import rpy_to_matrix
from mavreg.sim.closed_loop import SimOptions, simulate
from harness import params
from tests.helpers.repo import ROOT as REPO

VEHICLE = params.vehicle()
PERIOD = 0.002


def _open_loop(delay_s: float, tau_s: float, duration_s: float = 0.6):
    """The design model, rotors lagging by tau, commands (a hover plus sine differentials)
    reaching the rotors delay_s after they were issued; returns the run and the commands."""
    hover = VEHICLE.mass_kg * G / 4
    calls = []

    def controller(t, x):
        c = hover + np.array([0.8 * math.sin(9 * t), 0.5 * math.cos(7 * t),
                              -0.6 * math.sin(11 * t), 0.3 * math.cos(5 * t)])
        calls.append((t, c))
        return c

    x0 = np.zeros(12)
    x0[2], x0[6] = -5.0, 3.0
    opts = SimOptions(initial_state=tuple(x0), dt_s=0.001, control_period_steps=2,
                      max_duration_s=duration_s, rotor_time_constant_s=tau_s,
                      command_delay_s=delay_s)
    run = simulate(QuadrotorModel.from_vehicle(VEHICLE),
                   Mixer.from_vehicle(VEHICLE), controller, opts)
    return run, calls


@pytest.mark.parametrize("delay_s", [0.010, 0.030, 0.060])
def test_prediction_matches_the_plant_across_a_known_delay(delay_s):
    tau = 0.02
    run, calls = _open_loop(delay_s, tau)
    pred = StatePredictor(dataclasses.replace(VEHICLE, rotor_time_constant_s=tau), max_step_s=PERIOD)
    pred.reset(calls[0][1])
    worst = np.zeros(4)
    for t, c in calls:
        i = int(round(t / 0.001))
        j = i + int(round(delay_s / 0.001))
        if j < len(run.t) and t > 0.1:
            x = run.x[i]
            p = pred.predict(t, x, rpy_to_matrix(*x[3:6]), delay_s)
            truth = run.x[j]
            err = p.x - truth
            worst = np.maximum(worst, [np.abs(err[:3]).max(), np.abs(err[3:6]).max(),
                                       np.abs(err[6:9]).max(), np.abs(err[9:]).max()])
        pred.record(t, c)
    # Position, attitude, body velocity, body rates: the integration error of 2 ms steps
    # against the simulator's 1 ms RK4, far below a sensor's noise.
    assert worst[0] < 2e-5 and worst[1] < 2e-4 and worst[2] < 2e-4 and worst[3] < 5e-3, worst


def test_without_prediction_the_same_delay_is_a_large_error():
    """The reference of the test above: the sample itself is far from the state it must
    stand for (the predictor's whole job)."""
    run, _ = _open_loop(0.03, 0.02)
    i, j = 300, 330
    assert np.abs(run.x[j, 9:] - run.x[i, 9:]).max() > 5e-2


def test_free_fall_is_exact():
    pred = StatePredictor(VEHICLE, max_step_s=PERIOD)
    x = np.zeros(12)
    x[6:9] = (1.0, -2.0, 0.5)
    p = pred.predict(0.0, x, np.eye(3), 0.05)
    expected = x[6:9] * 0.05 + np.array([0, 0, 0.5 * G * 0.05 ** 2])
    np.testing.assert_allclose(p.x[:3], expected, atol=1e-12)
    np.testing.assert_allclose(p.x[6:9], x[6:9] + [0, 0, G * 0.05], atol=1e-12)


def test_hover_stays_and_lagged_forces_settle():
    tau = 0.03
    pred = StatePredictor(dataclasses.replace(VEHICLE, rotor_time_constant_s=tau), max_step_s=PERIOD)
    hover = VEHICLE.mass_kg * G / 4
    pred.reset([hover] * 4)
    x = np.zeros(12)
    x[2] = -3.0
    for k in range(50):
        pred.record(k * PERIOD, [hover] * 4)
    p = pred.predict(50 * PERIOD, x, np.eye(3), 0.02)
    np.testing.assert_allclose(p.x, x, atol=1e-12)
    np.testing.assert_allclose(p.rotor_forces_n, hover, rtol=1e-12)


def test_rotor_state_follows_the_lag_of_acted_commands():
    """A step command that acted for time a has the lag's value 1 - exp(-a / tau)."""
    tau, H = 0.02, 0.01
    pred = StatePredictor(dataclasses.replace(VEHICLE, rotor_time_constant_s=tau), max_step_s=PERIOD)
    pred.reset([0.0] * 4)
    pred.rotor_forces(0.0, H)
    pred.record(0.0, [2.0] * 4)          # acts from 0.01 s on
    f = pred.rotor_forces(0.04, H)
    np.testing.assert_allclose(f, 2.0 * (1 - math.exp(-0.03 / tau)), rtol=1e-12)


def test_horizon_is_capped_and_zero_is_the_identity():
    pred = StatePredictor(VEHICLE, max_step_s=PERIOD, max_horizon_s=0.05)
    x = np.zeros(12)
    x[:3] = (1.0, 2.0, -3.0)
    assert pred.predict(0.0, x, np.eye(3), 1.0).horizon_s == pytest.approx(0.05)
    p0 = pred.predict(0.0, x, np.eye(3), 0.0)
    np.testing.assert_allclose(p0.x, x, atol=0)


def test_forecaster_divides_commands_by_the_thrust_scale_and_predicts_with_it():
    from mavreg.control.estimation.forecast import Forecaster
    weak = dataclasses.replace(VEHICLE, rotor_time_constant_s=0.0, thrust_scale=0.9)
    fc = Forecaster(weak, PERIOD)
    hover = VEHICLE.mass_kg * G / 4
    fc.reset([hover] * 4)
    cmd = fc.command(0.0, [hover] * 4)
    np.testing.assert_allclose(cmd, hover / 0.9)
    np.testing.assert_allclose(fc.command(0.002, [20.0, -1.0, 5.0, 5.0]), [12.0, 0.0, 5 / 0.9, 5 / 0.9])
    fc.command(0.002, [hover] * 4)                 # a second answer to a sample replaces the first
    x = np.zeros(12)
    x[2] = -3.0
    f = fc.update(0.004, x, np.eye(3), 0.02)
    np.testing.assert_allclose(f.rotor_forces_n, hover, rtol=1e-12)   # physical force: hover
    np.testing.assert_allclose(f.x, x, atol=1e-12)                    # so it stays put


def test_command_history_stays_bounded_without_predictions():
    """A long-running daemon streams idle commands for hours before a maneuver: the history
    is folded into the rotor state instead of growing."""
    tau = 0.02
    pred = StatePredictor(dataclasses.replace(VEHICLE, rotor_time_constant_s=tau), max_step_s=PERIOD)
    for k in range(20000):
        pred.record(k * PERIOD, [1.0, 2.0, 3.0, 4.0])
    assert pred.pending <= 4097
    f = pred.rotor_forces(20000 * PERIOD, 0.0)
    np.testing.assert_allclose(f, [1.0, 2.0, 3.0, 4.0], rtol=1e-9)


def test_a_history_that_cannot_be_folded_is_kept_whole():
    """Commands that have not acted (asked for with a delay longer than the history) cannot
    be folded: the history's arrays grow, and every command is still there, in order."""
    pred = StatePredictor(dataclasses.replace(VEHICLE, rotor_time_constant_s=0.0), max_step_s=PERIOD)
    pred.rotor_forces(0.0, 1e3)
    n = 20000
    for k in range(n):
        pred.record(k * PERIOD, [k % 7, 0.0, 1.0, 2.0])
    assert pred.pending == n
    # now all acted (no delay): ideal rotors hold the last command, the others are dropped
    assert pred.rotor_forces((n - 1) * PERIOD + 1e-4, 0.0) == ((n - 1) % 7, 0.0, 1.0, 2.0)
    assert pred.pending == 1


def prediction_cases(n: int = 240) -> np.ndarray:
    """Seeded predictions, one row each (time, horizon, x, R, rotor forces): ideal and
    lagging rotors, drag on and off (linear, parasitic, an estimate in its place), a thrust
    scale, an external force, commands switching inside the horizon, a horizon past the cap,
    an explicit delay shorter than the horizon, and an empty command history."""
    rng = np.random.default_rng(3)
    rows = []
    for case in range(n):
        veh = dataclasses.replace(VEHICLE, rotor_time_constant_s=(0.0, 0.02, 0.03)[case % 3],
                                  rotor_drag_n_s_per_m=(0.3, 0.6) if case % 2 == 0 else (0.0, 0.0),
                                  parasitic_drag_n_s2_per_m2=0.01 if case % 4 == 0 else 0.0)
        pred = StatePredictor(veh, max_step_s=PERIOD, max_horizon_s=0.1)
        pred.reset(rng.uniform(0, 6, 4))
        t = 0.0
        for _ in range(0 if case % 10 == 0 else int(rng.integers(1, 40))):
            pred.record(t, rng.uniform(-1, 13, 4))
            t += float(rng.uniform(0.0015, 0.0025))
        x = rng.normal(size=12)
        x[3:6] = rng.uniform(-3, 3, 3)
        x[6:9] *= 5
        kw = {}
        if case % 3 == 1:
            kw["thrust_scale"] = 0.9
        if case % 7 == 2:
            kw["external_force_n"] = tuple(rng.normal(size=3))
        if case % 6 == 3:
            kw["drag_n_s_per_m"] = (0.2, 0.4)
        horizon = float(rng.uniform(0, 0.15))
        delay = None if case % 5 == 0 else float(rng.uniform(0, 0.05))
        p = pred.predict(max(t - float(rng.uniform(0, 0.03)), 0.0), x, rpy_to_matrix(*x[3:6]), horizon,
                         delay_s=delay, **kw)
        rows.append(np.concatenate([[p.time_s, p.horizon_s], p.x, p.rotation.ravel(), p.rotor_forces_n]))
    return np.array(rows)


def test_compiled_prediction_agrees_with_plain_python(tmp_path):
    """The prediction kernel compiled (numba) and as plain Python (MAVREG_PURE=1, a fresh
    process) give the same predictions to round-off, over the cases above."""
    import os
    import subprocess
    import sys
    code = ("import sys, numpy as np; from tests.unit.test_predictor import prediction_cases; "
            "np.save(sys.argv[1], prediction_cases())")
    out = {}
    for pure in ("0", "1"):
        path = tmp_path / f"p{pure}.npy"
        subprocess.run([sys.executable, "-c", code, str(path)], check=True, timeout=300, cwd=REPO,
                       env=dict(os.environ, MAVREG_PURE=pure))
        out[pure] = np.load(path)
    assert out["0"].shape == (240, 2 + 12 + 9 + 4) and np.all(np.isfinite(out["0"]))
    assert np.abs(out["0"] - out["1"]).max() <= 1e-12 * (1.0 + np.abs(out["1"]).max())
    assert out["0"][:, 1].max() == pytest.approx(0.1)          # some horizons were capped
