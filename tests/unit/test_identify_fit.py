"""The calibration fit (mavreg.identify.fit) on synthetic flights of known parameters."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tests.helpers.identify_synth import MASS_KG, MAX_ROTOR_N, synthetic_flight
from mavreg.identify.bootstrap import BlockBootstrap, integrated_time_rows
from mavreg.identify.fit import FitOptions, IdentifyError, identify, lagged_integrals

TRUTH = {"thrust_scale": 1.07, "drag": (0.25, 0.35, 0.15), "tau_s": 0.03, "delay_s": 0.0135}


def _exact_step_integrals(t_on, tau, h, n):
    """Closed form of the integral of 1 - exp(-(t - t_on)/tau) (0 before t_on) over [ih, (i+1)h]."""
    out = np.zeros(n)
    for i in range(n):
        a, b = max(i * h, t_on), (i + 1) * h
        if b <= a:
            continue
        if tau == 0:
            out[i] = b - a
        else:
            out[i] = (b - a) - tau * (math.exp(-(a - t_on) / tau) - math.exp(-(b - t_on) / tau))
    return out


@pytest.mark.parametrize("tau, delay", [(0.03, 0.0071), (0.03, 0.0), (0.0, 0.0131), (0.005, 0.004)])
def test_lagged_integrals_equal_the_closed_form_step_response(tau, delay):
    h, n, k0 = 0.002, 80, 5
    c = np.zeros(n + 1)
    c[k0:] = 1.0                                  # command k0 acts from k0 h + delay on
    got = lagged_integrals(c, h, tau, delay)
    want = _exact_step_integrals(k0 * h + delay, tau, h, n)
    assert np.allclose(got, want, atol=1e-12)


def test_lagged_integrals_sum_to_the_integral_of_a_lagged_random_signal():
    # the same signal integrated numerically with 1000 substeps per sample
    rng = np.random.default_rng(3)
    h, tau, delay = 0.002, 0.02, 0.0093
    c = rng.uniform(0, 10, 60)
    sub = 1000
    dt = h / sub
    f, total = 0.0, []
    acc = 0.0
    for i in range(59 * sub):
        t = i * dt
        k = math.floor((t + dt / 2 - delay) / h)
        u = c[k] if k >= 0 else 0.0
        f_new = u + (f - u) * math.exp(-dt / tau)
        acc += dt * (f + f_new) / 2
        f = f_new
        if (i + 1) % sub == 0:
            total.append(acc)
            acc = 0.0
    assert np.allclose(lagged_integrals(c, h, tau, delay), total, rtol=0, atol=2e-8)


def test_a_noise_free_flight_is_recovered_to_the_discretization():
    r = identify(synthetic_flight(noise_sd=0.0), MASS_KG, MAX_ROTOR_N)
    assert r.residual_rms_m_s2 < 1e-3 and r.r_squared > 0.999999
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=1e-4)
    for e, c in zip(r.drag_n_s_per_m, TRUTH["drag"]):
        assert e.value == pytest.approx(c, rel=1e-3)
    assert r.rotor_time_constant_s.value == pytest.approx(TRUTH["tau_s"], abs=2e-4)
    assert r.delay_s.value == pytest.approx(TRUTH["delay_s"], abs=2.6e-4)    # the fine grid's step
    p = r.parasitic_n_s2_per_m2.value
    assert p is None or abs(p) < 1e-4


def _covers(e, truth):
    return e.low <= truth <= e.high


@pytest.fixture(scope="module")
def noisy():
    """20 s, Gauss-Markov velocity noise (2 cm/s, 0.2 s), delay searched jointly with tau."""
    return identify(synthetic_flight(seed=4), MASS_KG, MAX_ROTOR_N)


def test_a_noisy_flight_is_recovered_within_a_few_percent(noisy):
    r = noisy
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=0.005)
    for e, c in zip(r.drag_n_s_per_m, TRUTH["drag"]):
        assert e.value == pytest.approx(c, rel=0.05)
    assert r.rotor_time_constant_s.value == pytest.approx(TRUTH["tau_s"], rel=0.1)
    assert r.delay_s.value == pytest.approx(TRUTH["delay_s"], abs=0.002)
    assert 0.3 < r.residual_rms_m_s2 < 1.0        # the differentiated velocity noise


def test_the_bootstrap_intervals_cover_the_truth(noisy):
    r = noisy
    assert _covers(r.thrust_scale, TRUTH["thrust_scale"])
    assert all(_covers(e, c) for e, c in zip(r.drag_n_s_per_m, TRUTH["drag"]))
    assert _covers(r.rotor_time_constant_s, TRUTH["tau_s"]) and _covers(r.delay_s, TRUTH["delay_s"])
    assert "moving-block bootstrap" in r.intervals


def test_a_known_delay_is_used_as_given():
    r = identify(synthetic_flight(seed=2), MASS_KG, MAX_ROTOR_N, FitOptions(delay_s=TRUTH["delay_s"]))
    assert r.delay_s.value == TRUTH["delay_s"] and r.delay_s.why == "given"
    assert r.rotor_time_constant_s.value == pytest.approx(TRUTH["tau_s"], rel=0.08)


def test_parasitic_drag_is_kept_when_the_flight_shows_it():
    r = identify(synthetic_flight(parasitic=0.02, seed=5), MASS_KG, MAX_ROTOR_N)
    assert r.model == "linear body drag + parasitic |v| v"
    assert r.parasitic_n_s2_per_m2.value == pytest.approx(0.02, rel=0.15)
    assert _covers(r.parasitic_n_s2_per_m2, 0.02)
    lin = identify(synthetic_flight(seed=5), MASS_KG, MAX_ROTOR_N)
    assert lin.model == "linear body drag" and lin.parasitic_n_s2_per_m2.value is None
    assert "includes 0" in lin.parasitic_n_s2_per_m2.why


def test_a_flight_without_thrust_changes_does_not_identify_the_rotor_lag():
    r = identify(synthetic_flight(excite=0.0, seed=6), MASS_KG, MAX_ROTOR_N)
    assert r.rotor_time_constant_s.value is None and "does not excite the rotor lag" in r.rotor_time_constant_s.why
    assert r.delay_s.value is None
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=0.01)


def test_a_hover_does_not_identify_drag():
    r = identify(synthetic_flight(excite=0.0, tilt_rad=0.0, duration_s=8.0), MASS_KG, MAX_ROTOR_N)
    assert r.model == "no drag (too slow)"
    assert all(e.value is None and "speed RMS" in e.why for e in r.drag_n_s_per_m)
    assert r.drag_xy_n_s_per_m.value is None and r.parasitic_n_s2_per_m2.value is None
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=0.01)


def test_drag_xy_is_the_inverse_variance_mean_of_x_and_y(noisy):
    cx, cy = noisy.drag_n_s_per_m[0].value, noisy.drag_n_s_per_m[1].value
    xy = noisy.drag_xy_n_s_per_m
    assert min(cx, cy) <= xy.value <= max(cx, cy) and xy.low < xy.value < xy.high


def test_samples_on_the_ground_or_not_in_offboard_are_left_out():
    s = synthetic_flight(duration_s=12.0, seed=7)
    n = s.t_s.size
    ctrl = np.ones(n, bool)
    ctrl[: n // 4] = False                         # before arming: on the ground at z = 0 ...
    pos = s.position_ned_m.copy()
    pos[: n // 4, 2] = 0.0
    pos[n // 4:, 2] = -0.1                         # ... and then below 0.3 m for a while
    pos[n // 2:, 2] = -5.0
    ground = dataclasses.replace(s, position_ned_m=pos, controlled=ctrl)
    r = identify(ground, MASS_KG, MAX_ROTOR_N)
    assert r.duration_s == pytest.approx(12.0 / 2, abs=0.1)
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=0.01)


def _one_line(exc_info):
    msg = str(exc_info.value)
    assert msg and "\n" not in msg
    return msg


def test_bad_inputs_are_one_line_errors():
    s = synthetic_flight(duration_s=6.0)
    empty = dataclasses.replace(s, t_s=np.zeros(0), position_ned_m=np.zeros((0, 3)),
                                velocity_ned_m_s=np.zeros((0, 3)), quaternion_wxyz=np.zeros((0, 4)),
                                controlled=np.zeros(0, bool))
    cases = {
        "usable telemetry samples": empty,
        "shape": dataclasses.replace(s, velocity_ned_m_s=s.velocity_ned_m_s[:, :2]),
        "controlled has": dataclasses.replace(s, controlled=s.controlled[:-3]),
        "of usable flight": dataclasses.replace(s, controlled=np.zeros(s.t_s.size, bool)),
        "no command could be placed": dataclasses.replace(s, command_t_s=np.full(s.t_s.size, np.nan)),
    }
    for words, series in cases.items():
        with pytest.raises(IdentifyError) as e:
            identify(series, MASS_KG, MAX_ROTOR_N)
        assert words in _one_line(e)
    nan = s.velocity_ned_m_s.copy()
    nan[::10] = np.nan                             # every 10th sample unusable: gaps everywhere
    with pytest.raises(IdentifyError) as e:
        identify(dataclasses.replace(s, velocity_ned_m_s=nan), MASS_KG, MAX_ROTOR_N,
                 FitOptions(max_gap_s=0.001))
    assert "of usable flight" in _one_line(e)
    with pytest.raises(IdentifyError) as e:
        identify(s, MASS_KG, MAX_ROTOR_N, FitOptions(window=20))
    assert "window" in _one_line(e)
    with pytest.raises(IdentifyError) as e:
        identify(s, MASS_KG, MAX_ROTOR_N, FitOptions(min_duration_s=10.0))
    assert "at least 10 s" in _one_line(e)


def _samples(s, keep):
    """The flight with only the telemetry samples ``keep`` says (the commands as they were)."""
    return dataclasses.replace(s, t_s=s.t_s[keep], position_ned_m=s.position_ned_m[keep],
                               velocity_ned_m_s=s.velocity_ned_m_s[keep],
                               quaternion_wxyz=s.quaternion_wxyz[keep], controlled=s.controlled[keep])


def test_short_telemetry_gaps_are_bridged():
    s = synthetic_flight(duration_s=20.0, seed=8)
    keep = np.ones(s.t_s.size, bool)
    keep[np.random.default_rng(0).choice(s.t_s.size, s.t_s.size // 50, replace=False)] = False   # 2 % lost
    lossy = _samples(s, keep)
    r = identify(lossy, MASS_KG, MAX_ROTOR_N, FitOptions(delay_s=TRUTH["delay_s"]))
    assert r.duration_s > 15.0
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=0.005)
    assert r.drag_n_s_per_m[1].value == pytest.approx(TRUTH["drag"][1], rel=0.05)


def test_gaps_of_a_few_periods_of_slower_telemetry_are_bridged_by_default():
    """PX4 asked for 200 Hz sends every 8 ms with one gap of 16-24 ms in twenty samples: by
    default gaps up to 3 periods are bridged and nearly the whole flight is used; pinned at
    10 ms (the old default) the same gaps cut most windows (negative control)."""
    s = synthetic_flight(duration_s=20.0, h=0.008, seed=8)
    keep = np.ones(s.t_s.size, bool)
    keep[np.random.default_rng(1).choice(np.arange(1, s.t_s.size - 1), s.t_s.size // 20, replace=False)] = False
    gappy = _samples(s, keep)
    r = identify(gappy, MASS_KG, MAX_ROTOR_N, FitOptions(delay_s=TRUTH["delay_s"]))
    assert r.duration_s > 17.0
    assert r.thrust_scale.value == pytest.approx(TRUTH["thrust_scale"], rel=0.01)
    pinned = identify(gappy, MASS_KG, MAX_ROTOR_N, FitOptions(delay_s=TRUTH["delay_s"], max_gap_s=0.01))
    assert pinned.duration_s < 0.6 * r.duration_s


# ------------------------------------------------------------------ bootstrap

def _ar1(n, a, seed):
    rng = np.random.default_rng(seed)
    x = np.zeros(n)
    e = rng.standard_normal(n)
    for k in range(1, n):
        x[k] = a * x[k - 1] + e[k]
    return x


def test_integrated_time_of_an_ar1_series():
    a = 0.8                                        # 1 + 2 sum a^k = (1 + a) / (1 - a) = 9
    assert integrated_time_rows(_ar1(200_000, a, 1)[:, None]) == pytest.approx(9.0, rel=0.1)
    assert integrated_time_rows(np.random.default_rng(2).standard_normal((50_000, 3))) == pytest.approx(1.0, abs=0.1)


def test_blocks_longer_than_the_memory_give_the_true_spread_of_a_mean():
    a, n = 0.9, 20_000
    x = _ar1(n, a, 3)
    true_se = math.sqrt((1 + a) / (1 - a) / (1 - a * a) / n)     # var(x) tau_int / n
    means = {}
    for block in (1, 400):
        bs = BlockBootstrap(n, 1, block, 400, seed=0)
        assert np.all(bs.weights >= 0) and np.all(bs.weights.sum(axis=1) >= bs.starts.size)
        sums = bs.replicate_sums(bs.chunk_sums(x))
        means[block] = np.std(sums / (bs.weights @ np.diff(np.append(bs.starts, n))))
    assert means[400] == pytest.approx(true_se, rel=0.3)
    assert means[1] < 0.4 * true_se                # samples drawn alone: far too optimistic
