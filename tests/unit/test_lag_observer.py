"""The observer's rotor-lag part: its sensitivity against finite differences of the lag filter,
convergence to the truth's time constant from either side in a closed-loop hover, no drift on
a vehicle that matches its file, the regulator's lead following it, and its settings."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mavreg.config.controller import load_controller
from mavreg.config.disturbance import DisturbanceParams, RotorLagParams, TorqueBiasParams
from mavreg.config.loader import ConfigError, load_text
from mavreg.config.paths import REAL_CONTROLLER
from mavreg.config.vehicle import with_output
from mavreg.control.estimation import lag_observer as lo
from mavreg.control.estimation.disturbance import DisturbanceObserver
from mavreg.control.estimation.forecast import Forecaster
from mavreg.control.controllers.hover import hold_ramp
from mavreg.control.estimation.predictor import StatePredictor
from harness import params
from tests.helpers.hover_loop import fly_hover

VEHICLE = params.vehicle()                     # the file: 20 ms rotors


def _lagged(c, dt, tau, f0=0.0):
    """The exact first-order lag of the held commands ``c`` (each for ``dt``): f at each
    step's end and its mean over the step."""
    e = math.exp(-dt / tau)
    f, ends, means = f0, [], []
    for ck in c:
        means.append(ck + (f - ck) * tau * (1.0 - e) / dt)
        f = ck + (f - ck) * e
        ends.append(f)
    return np.array(ends), np.array(means)


def test_the_regressor_is_the_lag_filters_derivative_in_its_time_constant():
    """Over a random command sequence at a 2 ms period (a hover's jitter and a slow swing),
    the kernel's regressor (body rate per second of time constant, per sample interval)
    matches the finite difference of the exact lag filter's integral in tau: the rate
    innovation a true lag of tau + delta would give."""
    rng = np.random.default_rng(1)
    dt, tau, n = 0.002, 0.02, 2000
    c = 0.3 * np.sin(np.arange(n) * dt * 6.0) + rng.normal(0.0, 0.05, n)
    ends, means = _lagged(c, dt, tau)
    d = 1e-6
    _, means_d = _lagged(c, dt, tau + d)
    want = (means_d - means) * dt / d                  # d/dtau of the interval's integral
    state = np.zeros(lo.SIZE)
    state[lo.TAU] = tau
    got, prev, phi = [], 0.0, np.empty(3)
    for k in range(n):
        lo.advance_sensitivity(state, dt, np.ones(3), np.full(3, ends[k] - prev), phi)
        got.append(phi[0])
        prev = ends[k]
    got = np.array(got)
    # within the kernel's approximation (the force's slope held over each interval)
    assert np.corrcoef(got[100:], want[100:])[0, 1] > 0.95
    assert np.std(got[100:] - want[100:]) < 0.3 * np.std(want[100:])
    # negative control: a regressor of the force's level, not its change, does not match
    assert abs(np.corrcoef(ends[100:], want[100:])[0, 1]) < 0.5


def _observing(enabled: bool) -> DisturbanceParams:
    return DisturbanceParams(enabled=True, torque_bias=TorqueBiasParams(enabled=True),
                             rotor_lag=RotorLagParams(enabled=enabled))


def _hover_flight(true_tau_s: float, disturbance: DisturbanceParams, seconds: float = 6.0, seed: int = 0):
    """A closed-loop hover of the hover LQR on the design model about a hold point that hops
    around a 0.3 m square every half second (as a position-hold's corrections), the truth's
    rotors of time constant ``true_tau_s`` (the controller's file says 20 ms), a white torque
    noise of 0.03 N m per axis (the paper's 0.1 N per rotor on 0.3 m arms), 12 ms of predicted
    delay, the rates measured with 5 mrad/s of white noise. Returns the forecaster."""
    dt = 0.002
    fc = Forecaster(VEHICLE, dt, predict=True, disturbance=disturbance)
    truth = StatePredictor(dataclasses.replace(VEHICLE, rotor_time_constant_s=true_tau_s), max_step_s=dt,
                           max_horizon_s=0.1)
    ramps = [hold_ramp(np.array([n, e, -10.0]), 0.0) for n, e in ((0.0, 0.0), (0.3, 0.0), (0.3, 0.3), (0.0, 0.3))]
    fly_hover(fc, truth, lambda t: ramps[int(t / 0.5) % 4], seconds, np.random.default_rng(seed),
              truth_torque=lambda rng: (*rng.normal(0.0, 0.03, 3), 0.0, 0.0, 0.0), dt_s=dt)
    return fc


@pytest.mark.parametrize("true_tau_s", [0.012, 0.045])
def test_the_estimate_converges_to_the_rotors_time_constant_in_a_hover(true_tau_s):
    """From the file's 20 ms, on either side, within 1 ms in 4 s of position hold (the
    corrections are the excitation), the prediction lagging by it and the lead following
    within the follower's rate."""
    fc = _hover_flight(true_tau_s, _observing(True), seconds=4.0)
    lag = fc.observer.lag
    assert lag.estimate_s == pytest.approx(true_tau_s, abs=0.001)
    assert fc.predictor.tau == fc.rotor_lag.estimate_s == lag.estimate_s
    assert fc.rotor_lag.applied_s == pytest.approx(lag.estimate_s, abs=1e-4)
    assert lag.updates > 1000 and lag.rejected == 0


def test_on_a_vehicle_that_is_its_file_the_estimate_stays_and_without_the_part_nothing_moves():
    fc = _hover_flight(0.02, _observing(True), seconds=4.0)
    assert fc.observer.lag.estimate_s == pytest.approx(0.02, abs=0.001)
    off = _hover_flight(0.045, _observing(False), seconds=1.0)
    assert off.observer.lag is None and off.rotor_lag.estimate is None
    assert off.predictor.tau == off.rotor_lag.applied_s == 0.02


def test_a_gap_restarts_the_sensitivity_and_a_non_finite_sample_changes_nothing():
    state = np.zeros(lo.SIZE)
    state[lo.TAU] = state[lo.APPLIED] = 0.02
    state[lo.P] = 4e-4
    args = (np.ones(3), np.zeros(3), False, 0.0, 1e-4, 0.005, 0.1, 0.02)
    lo.update(state, 0.002, args[0], np.array([0.01, 0.0, 0.0]), *args[1:])
    assert state[lo.G0] != 0.0
    before = state.copy()
    assert lo.update(state, 0.002, args[0], np.array([np.nan, 0.0, 0.0]), *args[1:]) == lo.SKIPPED
    assert state[lo.TAU] == before[lo.TAU] and not state[lo.G0:].any()
    obs = lo.RotorLagObserver(RotorLagParams(enabled=True), VEHICLE)
    obs.state[lo.G0:] = 1.0
    obs.restart()
    assert not obs.state[lo.G0:].any() and obs.estimate_s == 0.02


def test_the_shipped_controller_estimates_the_lag_and_the_loader_rejects_bad_settings():
    assert load_controller(REAL_CONTROLLER).disturbance.rotor_lag.enabled
    with pytest.raises(ConfigError, match="bounds_s"):
        load_text("enabled: true\nbounds_s: [0.05, 0.01]\n", RotorLagParams)
    with pytest.raises(ConfigError, match="lag_sd"):
        load_text("enabled: true\nlag_sd: 0.01\n", RotorLagParams)


def test_with_rates_to_an_autopilot_the_lag_is_the_files():
    """Through an autopilot's rate loop the wrench's lag is the output's realization and the
    identified rate loop (the vehicle file's), not the rotors': no lag part there."""
    on = _observing(True)
    assert DisturbanceObserver(on, VEHICLE).lag is not None
    rates = DisturbanceObserver(on, with_output(VEHICLE, "rates"))
    assert rates.lag is None
    assert Forecaster(with_output(VEHICLE, "rates"), 0.002, disturbance=on).rotor_lag.estimate is None


def test_with_rates_to_an_autopilot_no_torque_bias_is_estimated():
    """The autopilot's rate loop integrates its rate error and so rejects a torque bias
    itself: the torque part is off there, on in the rotors output of the same file."""
    on = _observing(True)
    assert DisturbanceObserver(on, VEHICLE).torque is not None
    rates = DisturbanceObserver(on, with_output(VEHICLE, "rates"))
    assert rates.torque is None and rates.estimate.torque_bias == (0.0,) * 6
