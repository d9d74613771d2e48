"""The observer's torque part: convergence to a known torque bias in closed loop, its feed-forward
through the allocation, its bounds, gate and settings."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.controller import load_controller
from mavreg.config.disturbance import DisturbanceParams, TorqueBiasParams
from mavreg.config.loader import ConfigError
from mavreg.config.paths import REAL_CONTROLLER
from mavreg.config.vehicle import G
from mavreg.control.estimation.disturbance import DisturbanceEstimate
from mavreg.control.estimation.forecast import Forecaster
from mavreg.control.controllers.hover import HoverController, HoverParams, hold_ramp
from mavreg.control.estimation.predictor import StatePredictor
from mavreg.control.estimation.torque_bias import TorqueBiasObserver, allocated_less_bias, bias_vector_n_m
from mavreg.maneuver.plan_margins import hover_margins
from mavreg.model.mixer import Mixer, torques_first, yaw_then_lift
from harness import params
from tests.helpers.hover_loop import fly_hover

VEHICLE = params.vehicle()
HOVER_N = VEHICLE.mass_kg * G
TRUTH = (0.0, 0.0, 0.0, 0.008, -0.006, 0.004)
"""The truth's torque bias, all of it proportional to the thrust (t1, m): 0.06, -0.04 and
0.03 N m in a hover, as a centre of mass 6-8 mm off and rotors 4 % apart would give."""


def _observing(enabled: bool) -> DisturbanceParams:
    return DisturbanceParams(enabled=True, torque_bias=TorqueBiasParams(enabled=enabled))


def _hover_flight(disturbance: DisturbanceParams, seconds: float = 4.0, seed: int = 0,
                  extra_delay_s: float = 0.0):
    """A closed-loop hover of the hover LQR on the design model (the predictor as the truth,
    with the torque bias ``TRUTH`` and 12 ms of delay, predicted, plus ``extra_delay_s`` that
    the controller is not told), the rates measured with 5 mrad/s of white noise. Returns
    (forecaster, the last second's largest position and angle errors)."""
    dt = 0.002
    fc = Forecaster(VEHICLE, dt, predict=True, disturbance=disturbance)
    truth = StatePredictor(VEHICLE, max_step_s=dt, max_horizon_s=0.1)
    ramp = hold_ramp(np.array([0.0, 0.0, -10.0]), 0.0)
    x = fly_hover(fc, truth, lambda t: ramp, seconds, np.random.default_rng(seed), extra_delay_s=extra_delay_s,
                  truth_torque=lambda rng: TRUTH, dt_s=dt)[-int(1.0 / dt):]
    worst_m = float(np.linalg.norm(x[:, :3] - [0.0, 0.0, -10.0], axis=1).max())
    return fc, worst_m, float(np.abs(x[:, 3:6]).max())


def test_the_estimate_converges_to_the_torque_bias_in_closed_loop_and_the_hover_holds_its_point():
    fc, worst_m, worst_rad = _hover_flight(_observing(True))
    est = fc.observer.estimate.torque_bias
    np.testing.assert_allclose(est[3:], TRUTH[3:], atol=0.0008)      # within 10 % of the largest
    assert est[:3] == (0.0, 0.0, 0.0)                                # the constant part is off by default
    assert fc.observer.applied.torque_bias == pytest.approx(est, abs=1e-4)   # followed within 4 s
    assert worst_m < 0.01 and worst_rad < 0.002
    # negative control: without the torque part the same flight holds a steady offset
    off, off_m, off_rad = _hover_flight(_observing(False))
    assert off.observer.torque is None and off.observer.estimate.torque_bias == (0.0,) * 6
    assert off_m > 5 * worst_m and off_m > 0.03


def test_the_hover_keeps_its_delay_margin_with_the_torque_part():
    """The estimate is fed forward, not fed back (its innovations are the torque the prediction
    misses, whatever was commanded): with 0.8 x the hover's printed delay margin of delay the
    controller is not told, the hover holds and the estimate still converges; at 1.3 x it
    diverges, as it does without the torque part (``test_margins.py``)."""
    margin_s = hover_margins(VEHICLE)[0].delay_margin_s
    fc, worst_m, worst_rad = _hover_flight(_observing(True), seconds=5.0, extra_delay_s=0.8 * margin_s)
    assert worst_m < 0.01 and worst_rad < 0.02
    np.testing.assert_allclose(fc.observer.estimate.torque_bias[3:], TRUTH[3:], atol=0.0008)
    _, worst_m, _ = _hover_flight(_observing(True), seconds=5.0, extra_delay_s=1.3 * margin_s)
    assert worst_m > 1.0


def test_the_rotors_are_asked_for_the_wrench_less_the_bias_and_the_collective_is_untouched():
    hover = HoverController(VEHICLE, HoverParams())
    ramp = hold_ramp(np.zeros(3), 0.0)
    x = np.zeros(12)
    x[3], x[9] = 0.02, -0.1
    est = DisturbanceEstimate((0.0, 0.0), (0.0, 0.0, 0.0), 1.0, (0.01, 0.0, -0.02, 0.008, -0.006, 0.004))
    plain = hover.step(x, ramp, 0.0, DisturbanceEstimate((0.0, 0.0), (0.0, 0.0, 0.0), 1.0))
    out = hover.step(x, ramp, 0.0, est)
    np.testing.assert_allclose(out.u, plain.u)                        # the wrench wanted is the same
    achieved = Mixer.from_vehicle(VEHICLE).to_wrench(out.rotor_forces_n)
    bias = bias_vector_n_m(est.torque_bias, out.u[0])
    np.testing.assert_allclose(achieved[1:] + bias, out.u[1:], atol=1e-12)
    assert achieved[0] == pytest.approx(out.u[0])                     # no thrust the monitor could miss


@pytest.mark.parametrize("policy", [torques_first, yaw_then_lift])
def test_a_negative_collective_is_compensated_at_the_collective_the_rotors_give(policy):
    """At the barrel roll's exit the regulator asks for a negative collective with a large roll
    torque; the allocation lifts all four rotors. The bias is the airframe's at the thrust it
    then gets, not at the negative one asked for (which would flip its sign)."""
    mixer = Mixer.from_vehicle(VEHICLE)
    tb = (0.0, 0.0, 0.0, -0.0055, 0.0008, -0.0002)
    u = np.array([-2.6, 1.8, 0.1, 0.0])
    f = allocated_less_bias(policy, mixer.inverse, u, VEHICLE.max_rotor_thrust_n, tb)
    given = mixer.to_wrench(f)
    assert given[0] > 5.0                                             # lifted: the roll torque needs 6 N
    np.testing.assert_allclose(given[1:3] + bias_vector_n_m(tb, given[0])[:2], u[1:3], atol=1e-5)
    naive = policy(mixer.inverse, np.concatenate([u[:1], u[1:] - bias_vector_n_m(tb, u[0])]),
                   VEHICLE.max_rotor_thrust_n)
    assert abs(mixer.to_wrench(naive)[1] + bias_vector_n_m(tb, given[0])[0] - u[1]) > 0.03   # negative control


def test_estimate_is_bounded_and_an_outlier_is_refused():
    obs = TorqueBiasObserver(TorqueBiasParams(enabled=True, max_per_thrust_m=0.01), VEHICLE)
    for _ in range(3000):
        obs.update(0.002, HOVER_N, (0.01, 0.0, 0.0))                 # 0.09 N m of roll: 0.012 m
    assert obs.theta[3] == pytest.approx(0.01)
    assert obs.theta_applied[3] <= 0.01 + 1e-12
    before, rejected = obs.theta.copy(), obs.rejected
    assert not obs.update(0.002, HOVER_N, (3.0, 0.0, 0.0))           # a jump of 3 rad/s in 2 ms
    assert obs.rejected == rejected + 1 and np.array_equal(obs.theta, before)
    assert not obs.update(0.002, HOVER_N, (np.nan, 0.0, 0.0))


def test_torque_bias_section_of_the_controller_file(tmp_path):
    assert not DisturbanceParams().torque_bias.enabled                    # off unless a file says so
    assert load_controller(REAL_CONTROLLER).disturbance.torque_bias.enabled
    text = REAL_CONTROLLER.read_text()
    section = "  torque_bias:\n    enabled: true\n"
    assert section in text
    bad = tmp_path / "c.yaml"
    bad.write_text(text.replace(section, "  torque_bias:\n    enable: true\n"))
    with pytest.raises(ConfigError, match="enable"):
        load_controller(bad)
    good = tmp_path / "g.yaml"
    good.write_text(text.replace(section, section + "    per_thrust_sd_m: 0.02\n"))
    tb = load_controller(good).disturbance.torque_bias
    assert tb.enabled and tb.per_thrust_sd_m == 0.02


def test_the_flight_summary_prints_the_torque_estimate():
    from mavreg.daemon.jobs.report import format_summary
    est = {"drag_n_s_per_m": [0.381, 0.642], "force_ned_n": [-1.1, 0.02, 0.0], "thrust_scale": 0.903,
           "updates": 27000, "rejected": 3}
    summary = {"result": "ok", "maneuver": "barrel_roll", "length_m": 40.47, "flight_time_s": 59.0,
               "status": {"disturbance": {**est, "torque_bias": {
                   "constant_n_m": [0.0, 0.0, 0.0], "per_thrust_m": [-0.0055, 0.0004, -0.0002],
                   "updates": 26000, "rejected": 1}}}}
    text = format_summary(summary)
    assert ("torque bias as estimated: t1 -5.5 +0.4 -0.2 mm (N m per N of thrust), t0 +0.000 +0.000 +0.000 N m "
            "(26000 samples, 1 refused)") in text
    assert "torque bias" not in format_summary({**summary, "status": {"disturbance": est}})
