"""Delay and gain margins (mavreg.control.design.margins, mavreg.maneuver.plan_margins): closed forms,
against the simulator on the design model, and the default controller's targets (issue 18)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.model.rotor_lag import lag_augment
from mavreg.control.controllers.hover import HoverController, HoverParams, hold_ramp
from mavreg.control.design.margins import (delay_margins, gain_margins, lag_model_loop, loop_margins, node_margins,
                                    rotor_loop, schedule_margins, spectral_abscissa)
from mavreg.daemon.flight.gate import HealthGate, MarginCheck, delay_margin_of, unmodelled_delay_s
from mavreg.config.envelope import EnvelopeParams
from mavreg.planning.plan_io import plan_file
from mavreg.maneuver.plan_margins import SLOW_RAD_S, hover_margins, maneuver_loops, with_margins
from mavreg.model.mixer import Mixer, mixer_matrix
from mavreg.model.quadrotor import QuadrotorModel
from mavreg.sim.closed_loop import SimOptions, simulate
from mavreg.sim.maneuver_run import fly_on_design_model

BARREL = maneuver_file("barrel_roll")


# ----------------------------------------------------------------------------- closed forms
@pytest.mark.parametrize("k", [0.5, 3.0, 40.0])
def test_scalar_delay_margin_is_pi_over_2k(k):
    m = loop_margins([[0.0]], [[1.0]], [[k]])
    assert m.delay_margin_s == pytest.approx(math.pi / (2 * k), rel=1e-8)
    assert m.crossover_rad_s == pytest.approx(k, rel=1e-8)
    assert m.gain_margin_low == 0.0 and m.gain_margin_high == math.inf    # x' = -g k x: any g > 0


def test_double_integrator_pd_delay_margin():
    """x'' = u, u = -kp x - kd x': |L(jw)| = 1 at w^2 = (kd^2 + sqrt(kd^4 + 4 kp^2)) / 2, and
    tau = (arg L - pi mod 2 pi) / w with L = (kp + j kd w) / (-w^2)."""
    kp, kd = 4.0, 3.0
    w = math.sqrt((kd ** 2 + math.sqrt(kd ** 4 + 4 * kp ** 2)) / 2)
    tau = (np.angle((kp + 1j * kd * w) / -w ** 2) - math.pi) % (2 * math.pi) / w
    m = loop_margins([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0]], [[kp, kd]])
    assert m.delay_margin_s == pytest.approx(tau, rel=1e-8)
    assert m.gain_margin_low == 0.0 and m.gain_margin_high == math.inf


def test_third_order_lag_finite_gain_margin():
    """L = k / (s + 1)^3: (s + 1)^3 + g k = 0 on the axis at s = j sqrt(3), g k = 8."""
    k = 2.0
    A = np.array([[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0], [0.0, 0.0, -1.0]])
    B = np.array([[0.0], [0.0], [1.0]])
    K = np.array([[k, 0.0, 0.0]])
    m = loop_margins(A, B, K)
    assert m.gain_margin_high == pytest.approx(8.0 / k, rel=1e-3)
    assert m.gain_margin_high >= 8.0 / k                       # reported on the unstable side
    assert m.gain_margin_low == 0.0
    w = math.sqrt(k ** (2 / 3) - 1)
    assert m.delay_margin_s == pytest.approx((math.pi - 3 * math.atan(w)) / w, rel=1e-8)


def test_unstable_plant_lower_gain_margin():
    """x' = a x + u, u = -k x: stable iff g k > a."""
    a, k = 2.0, 5.0
    lo, hi = gain_margins([[a]], [[1.0]], [[k]])
    assert lo[0] == pytest.approx(a / k, rel=1e-3) and lo[0] <= a / k * (1 + 1e-3)
    assert hi[0] == math.inf
    loop = ([[a]], [[1.0]], [[k]])
    assert spectral_abscissa(*loop, lo[0] * 0.99) > 0 > spectral_abscissa(*loop, lo[0] * 1.01)


def test_unstable_nominal_is_nan_and_left_out_of_a_schedule():
    A = np.array([[[0.0]], [[0.0]], [[0.0]]])
    B = np.ones((3, 1, 1))
    K = np.array([[[2.0]], [[-1.0]], [[4.0]]])                 # the middle one is unstable
    tau, lo, hi = node_margins(A, B, K)
    assert math.isnan(tau[1]) and math.isnan(lo[1])
    worst = schedule_margins([0.0, 1.0, 2.0], tau, lo, hi)
    assert worst.delay_margin_s == pytest.approx(math.pi / 8) and worst.worst_s_m == 2.0
    assert worst.unstable_s_m == ((0.0, 2.0),)


def test_slow_modes_are_not_judged_when_asked():
    A = np.diag([0.5, 0.0])                                    # a slow unstable mode, uncontrolled
    B = np.array([[0.0], [1.0]])
    K = np.array([[0.0, 10.0]])
    assert math.isnan(delay_margins(A, B, K)[0][0])
    tau, _ = delay_margins(A, B, K, slow_rad_s=1.0)
    assert tau[0] == pytest.approx(math.pi / 20)


def test_lag_model_loop_spectrum_and_rotor_loops():
    """Nominally the controller's lag model equals the plant's lag: the spectrum is that of
    A - BK plus the lag's own; every single-rotor loop closes to the same A - BK."""
    rng = np.random.default_rng(1)
    A0, B0 = rng.normal(size=(3, 3)), rng.normal(size=(3, 4))
    A, B = lag_augment(A0, B0, 0.02)
    K = rng.normal(size=(4, 7))
    Ac, Bc, Kc = lag_model_loop(A, B, K)
    got = np.sort_complex(np.linalg.eigvals(Ac[0] - Bc[0] @ Kc[0]))
    want = np.sort_complex(np.concatenate([np.linalg.eigvals(A - B @ K), np.full(4, -50.0)]))
    assert np.allclose(got, want, atol=1e-8)
    M = mixer_matrix(0.3, 0.016)
    for i in range(4):
        Ai, Bi, Ki = rotor_loop(A, B, K, M, i)
        assert np.allclose(Ai - Bi @ Ki, A - B @ K)


# ----------------------------------------------------------------------------- the hover
@pytest.fixture(scope="module")
def vehicle():
    return load_vehicle(DEFAULT_VEHICLE)


@pytest.fixture(scope="module")
def hover(vehicle):
    return hover_margins(vehicle)[0]


def _hover_flight(vehicle, delay_s=0.0, gain=1.0, duration_s=8.0):
    """The hover LQR holding a point from a 0.2 m, 3 deg offset on the design model with the rotor
    lag; ``gain`` scales the feedback part of the rotor commands, ``delay_s`` delays them.
    Returns (status, peak |position error| over the first and over the last second)."""
    ctl = HoverController(vehicle, HoverParams())
    mixer = Mixer.from_vehicle(vehicle)
    ramp = hold_ramp(np.zeros(3), 0.0)
    _, u_ref = ctl.reference(ramp, 0.0)

    def controller(t, x):
        u = ctl.step(x, ramp, t).u
        return mixer.inverse @ (u_ref + gain * (u - u_ref))

    x0 = np.zeros(12)
    x0[:3] = (0.2, -0.1, 0.1)
    x0[3] = math.radians(3.0)
    res = simulate(QuadrotorModel.from_vehicle(vehicle), mixer, controller,
                   SimOptions(initial_state=x0, dt_s=1e-3, max_duration_s=duration_s,
                              rotor_time_constant_s=vehicle.rotor_time_constant_s, command_delay_s=delay_s))
    err = np.linalg.norm(res.x[:, :3], axis=1)
    return res.status.value, float(err[res.t < 1.0].max()), float(err[res.t > res.t[-1] - 1.0].max())


def test_default_hover_meets_the_targets(vehicle, hover):
    assert hover.delay_margin_s >= 0.025
    assert hover.gain_margin_low <= 0.7 and hover.gain_margin_high >= 1.3
    rotor = hover_margins(vehicle)[1]
    assert rotor.delay_margin_s >= 0.025 and rotor.gain_margin_low <= 0.7 and rotor.gain_margin_high >= 1.3


def test_hover_delay_margin_against_the_simulator(vehicle, hover):
    """0.8 x the margin: the offset decays; 1.3 x: it grows (the frozen-time analysis is exact
    for a hover; the simulator's delay is rounded to its 1 ms step, the command held 1 ms)."""
    status, first, last = _hover_flight(vehicle, delay_s=0.8 * hover.delay_margin_s)
    assert status != "diverged" and last < 0.05 * first
    status, first, last = _hover_flight(vehicle, delay_s=1.3 * hover.delay_margin_s)
    assert status == "diverged" or last > first


def test_hover_gain_margin_against_the_simulator(vehicle, hover):
    status, first, last = _hover_flight(vehicle, gain=1.1 * hover.gain_margin_low, duration_s=20.0)
    assert status != "diverged" and last < 0.5 * first
    status, first, last = _hover_flight(vehicle, gain=0.8 * hover.gain_margin_low, duration_s=20.0)
    assert status == "diverged" or last > first


# ----------------------------------------------------------------------------- the barrel roll
@pytest.fixture(scope="module")
def realistic_plan(vehicle):
    return with_margins(plan_file(BARREL, vehicle, load_controller(REAL_CONTROLLER)))


EXIT_BLEND_M = (29.3, 30.4)
"""Where the barrel roll's frozen loop has a lightly damped ~8 rad/s pair (the thrust falls from
34 to 6 N in 0.4 s): its frozen lower gain edge is not a fair figure (docs/robustness.md)."""


def test_default_controller_meets_the_targets_along_the_barrel_roll(realistic_plan):
    m = realistic_plan.margins.maneuver
    assert m.delay_margin_s >= 0.025
    assert m.gain_margin_high >= 1.3
    assert m.unstable_s_m == ()
    rows = np.arange(0, len(realistic_plan.s), 97)
    rows = rows[(realistic_plan.s[rows] < EXIT_BLEND_M[0]) | (realistic_plan.s[rows] > EXIT_BLEND_M[1])]
    _, lo, _ = node_margins(*maneuver_loops(realistic_plan, rows), slow_rad_s=SLOW_RAD_S)
    assert np.nanmax(lo) <= 0.7 and not np.isnan(lo).any()


def test_barrel_roll_with_most_of_its_delay_margin_on_the_design_model(realistic_plan, vehicle):
    """0.8 x the reported delay margin of extra command delay (not predicted), the 20 ms rotor
    lag, 500 Hz: the roll is flown to the end and the error has decayed on the slow run-out."""
    tau = realistic_plan.margins.maneuver.delay_margin_s
    run = fly_on_design_model(realistic_plan, rotor_time_constant_s=vehicle.rotor_time_constant_s,
                              command_delay_s=0.8 * tau, control_rate_hz=500.0, start_s_m=14.0,
                              extra_time_s=2.0)
    assert run.metrics["completed"], run.metrics["reason"]
    e = np.hypot(run.w[:, 0], run.w[:, 1])
    assert e.max() < 0.3
    assert e[run.s > 38.0].max() < 0.2 * e.max()


def test_barrel_roll_with_the_issues_25_ms_of_extra_delay_and_past_it(realistic_plan, vehicle):
    """The target itself: 25 ms of command delay the controller does not know of (no
    prediction), the 20 ms rotor lag, 500 Hz, the whole roll from the entry: flown to the end
    within 30 cm (17 cm measured). Negative control: 35 ms, past the margin, is lost (2.4 m)."""
    def worst(delay_s):
        run = fly_on_design_model(realistic_plan, rotor_time_constant_s=vehicle.rotor_time_constant_s,
                                  command_delay_s=delay_s, control_rate_hz=500.0, extra_time_s=2.0)
        return run.metrics["completed"], float(np.hypot(run.w[:, 0], run.w[:, 1]).max())
    completed, e = worst(0.025)
    assert completed and e < 0.30
    assert worst(0.035)[1] > 1.0


def test_barrel_roll_with_every_rotor_at_70_percent_completes(realistic_plan, vehicle, monkeypatch):
    """The loop survives the -30 % rotor gain (feedforward included: the thrust deficit itself
    pulls the vehicle off the path, but nothing diverges)."""
    import dataclasses
    import mavreg.sim.maneuver_run as mr
    real = mr.simulate
    monkeypatch.setattr(mr, "simulate",
                        lambda m, x, c, o: real(m, x, c, dataclasses.replace(o, thrust_scale=0.7)))
    run = fly_on_design_model(realistic_plan, rotor_time_constant_s=vehicle.rotor_time_constant_s,
                              control_rate_hz=500.0, start_s_m=14.0, extra_time_s=2.0)
    assert run.metrics["completed"], run.metrics["reason"]


def test_plan_summary_carries_the_margins(realistic_plan):
    d = realistic_plan.summary()["margins"]
    assert d["maneuver"]["delay_margin_ms"] >= 25.0 and d["hover"]["delay_margin_ms"] >= 25.0
    assert d["rotor_time_constant_s"] == 0.02


# ----------------------------------------------------------------------------- the gate
def test_unmodelled_delay():
    assert unmodelled_delay_s(0.016, 0.0015, None) == 0.016
    assert unmodelled_delay_s(0.002, 0.0, None, 0.002) == 0.0            # TIMESYNC's extra period
    assert unmodelled_delay_s(0.016, 0.0015, 0.016) == pytest.approx(0.0045)
    assert unmodelled_delay_s(0.150, 0.001, 0.1) == pytest.approx(0.053)


def test_gate_refuses_a_delay_beyond_half_the_margin(realistic_plan):
    margin, what = delay_margin_of(realistic_plan)
    assert what == "maneuver 'barrel_roll'" and margin == realistic_plan.margins.maneuver.delay_margin_s
    link = [0.6 * margin, 0.0005]
    gate = HealthGate(EnvelopeParams(), 0.749, 12.0, lambda: tuple(link))
    v = gate.link_verdict(MarginCheck(margin, what, None))    # not predicted: all of it counts
    assert not v.ok and v.bound == "gate_delay_margin"
    assert f"{0.6 * margin * 1e3:.1f} ms" in v.detail and f"{margin * 1e3:.1f} ms" in v.detail
    assert gate.link_verdict(MarginCheck(margin, what, 0.6 * margin)) is None   # predicted: the jitter counts
    assert not gate.link_verdict(MarginCheck(margin, what, 0.05 * margin)).ok   # a horizon too short
    link[0] = 0.4 * margin
    assert gate.link_verdict(MarginCheck(margin, what, None)) is None
    assert gate.link_verdict() is None                        # no margins: not checked
