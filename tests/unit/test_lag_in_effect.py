"""One holder of the rotor lag in effect (issue 31, item 3): when the in-flight estimate
moves, every user of the lag follows it at once, and each behaves as it would on a vehicle
file that had that lag; a user that kept a copy would not (the negative control)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mavreg.config.controller import load_controller
from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER, maneuver_file
from mavreg.config.vehicle import load_vehicle, with_output
from mavreg.control.controllers.regulator import ManeuverRegulator
from mavreg.control.estimation import lag_observer as lo
from mavreg.control.estimation.forecast import Forecaster
from mavreg.control.estimation.lag_in_effect import RotorLagInEffect, plant_lag_s
from mavreg.control.estimation.predictor import StatePredictor
from mavreg.daemon.flight.output import RateOutput
from mavreg.daemon.vehicle.peers import VehicleIds
from mavreg.maneuver.plan_margins import plan_margins
from mavreg.planning.plan_io import plan_file

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
CONTROLLER = load_controller(REAL_CONTROLLER)
PERIOD_S = 0.002
ESTIMATE_S, APPLIED_S = 0.045, 0.037
"""The in-flight estimate moved off the file's 20 ms, and its follower part of the way."""


def _flight() -> Forecaster:
    """A flight's forecaster with the shipped controller's observer (its rotor-lag part on)."""
    fc = Forecaster(VEHICLE, PERIOD_S, disturbance=CONTROLLER.disturbance)
    assert fc.observer.lag is not None and fc.rotor_lag.estimate is fc.observer.lag
    return fc


def _move_the_estimate(fc: Forecaster) -> None:
    """What the lag observer's filter does over a hover, in one step."""
    fc.observer.lag.state[lo.TAU] = ESTIMATE_S
    fc.observer.lag.state[lo.APPLIED] = APPLIED_S


def _with_lag(tau_s: float):
    return dataclasses.replace(VEHICLE, rotor_time_constant_s=tau_s)


def _commands(predictor: StatePredictor) -> np.ndarray:
    """A prediction across 40 ms of a rotor-command step recorded on ``predictor``."""
    predictor.reset((1.8,) * 4)
    for k in range(10):
        predictor.record(k * PERIOD_S, (2.4, 1.2, 2.4, 1.2))
    x = np.zeros(12)
    x[2] = -3.0
    return predictor.predict_raw(0.0, x, np.eye(3), 0.04, delay_s=0.002)


def test_the_holder_answers_the_file_then_the_estimate():
    fc = _flight()
    assert fc.rotor_lag.file_s == fc.rotor_lag.estimate_s == fc.rotor_lag.applied_s == 0.02
    _move_the_estimate(fc)
    assert (fc.rotor_lag.estimate_s, fc.rotor_lag.applied_s, fc.rotor_lag.file_s) == (ESTIMATE_S, APPLIED_S, 0.02)


def test_the_prediction_follows_the_estimate():
    fc = _flight()
    _move_the_estimate(fc)
    assert fc.predictor.tau == ESTIMATE_S
    np.testing.assert_array_equal(_commands(fc.predictor), _commands(StatePredictor(_with_lag(ESTIMATE_S),
                                                                                    PERIOD_S, 0.1)))
    # the negative control: a predictor that kept the file's value predicts otherwise
    kept = _commands(StatePredictor(VEHICLE, PERIOD_S, 0.1))
    assert np.abs(kept[21:25] - _commands(fc.predictor)[21:25]).max() > 0.01


@pytest.fixture(scope="module")
def plan():
    return plan_file(maneuver_file("slalom"), VEHICLE, CONTROLLER)


def _steps(reg: ManeuverRegulator, plan) -> np.ndarray:
    """The rotor commands of 50 steps from 10 cm off the entry."""
    x = plan.entry_state.copy()
    x[:3] += 0.1
    reg.reset(x)
    out = []
    for k in range(50):
        x = plan.nominal_state(0.1 * k)
        x[:3] += 0.05
        out.append(reg.step(x).rotor_forces_n)
    return np.array(out)


@pytest.mark.parametrize("compiled", [False, True])
def test_the_regulators_lead_follows_the_estimates_follower(plan, compiled):
    fc = _flight()
    reg = ManeuverRegulator(plan, VEHICLE, PERIOD_S, rotor_lag=fc.rotor_lag, compiled=compiled)
    before = _steps(reg, plan)
    _move_the_estimate(fc)
    after = _steps(reg, plan)
    same = _steps(ManeuverRegulator(plan, _with_lag(APPLIED_S), PERIOD_S, compiled=compiled), plan)
    np.testing.assert_allclose(after, same, rtol=0, atol=1e-12)
    assert np.abs(after - before).max() > 1e-3       # the negative control: the file's lead differs


def test_the_rates_outputs_torque_lag_follows_it():
    """The rates output lags the torque it asks the autopilot's rate loop for by the same
    answer (a holder with an estimate stands in: the observer's lag part is off with rates)."""
    rates = with_output(VEHICLE, "rates")
    estimate = lo.RotorLagObserver(CONTROLLER.disturbance.rotor_lag, rates)
    out = RateOutput(rates, VehicleIds(1), RotorLagInEffect.of_vehicle(rates, estimate))
    estimate.state[lo.APPLIED] = APPLIED_S
    same = RateOutput(dataclasses.replace(rates, rotor_time_constant_s=APPLIED_S), VehicleIds(1))
    kept = RateOutput(rates, VehicleIds(1))
    forces = [np.array([2.0, 1.5, 2.0, 1.5]), np.array([1.5, 2.0, 1.5, 2.0])] * 5
    got, want, old = ([o.command(f, np.zeros(12), 0.004 * k)[0] for k, f in enumerate(forces)]
                      for o in (out, same, kept))
    np.testing.assert_array_equal(np.array(got), np.array(want))
    assert np.abs(np.array(got) - np.array(old)).max() > 1e-3


def test_a_plans_margins_are_on_its_design_lag_or_its_files(plan):
    assert plan.rotor_time_constant_s == 0.02 and plant_lag_s(plan) == 0.02
    ideal_gains = dataclasses.replace(plan, rotor_time_constant_s=0.0, vehicle=_with_lag(0.03))
    assert plant_lag_s(ideal_gains) == 0.03
    assert plan_margins(plan).rotor_time_constant_s == plant_lag_s(plan)
