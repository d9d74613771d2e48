"""TIMESYNC: the sample-to-actuation delay on the vehicle's clock, robust to outliers."""
import numpy as np
import pytest

from mavreg.daemon.vehicle.timesync import TimesyncEstimator


def _exchange(est, sample_t, delay, now_ns):
    ts1 = est.request(now_ns, sample_t)
    return est.reply(int(round((sample_t + delay) * 1e9)), ts1, now_ns + 3_000_000)


def test_known_delay_is_measured_without_any_clock_offset():
    est = TimesyncEstimator(request_period_s=0.1)
    assert est.estimate() is None
    # The daemon's clock is unrelated to the vehicle's (offset 1234 s): it must not matter.
    for k in range(20):
        assert _exchange(est, 10.0 + 0.1 * k, 0.017, 1234_000_000_000 + k * 100_000_000)
    e = est.estimate()
    assert e.delay_s == pytest.approx(0.017, abs=1e-9)
    assert e.jitter_s == pytest.approx(0.0, abs=1e-9)
    assert e.round_trip_s == pytest.approx(0.003)
    assert e.samples == 20


def test_median_ignores_outliers_and_jitter_is_a_standard_deviation():
    est = TimesyncEstimator(window=301)
    rng = np.random.default_rng(5)
    delays = 0.015 + 0.002 * rng.standard_normal(300)
    delays[::30] = 0.4                         # one reply in 30 badly late
    for k, d in enumerate(delays):
        _exchange(est, 1.0 + 0.1 * k, d, k * 100_000_000)
    e = est.estimate()
    assert e.delay_s == pytest.approx(0.015, abs=5e-4)
    assert e.jitter_s == pytest.approx(0.002, rel=0.2)


def test_foreign_unknown_and_implausible_replies_are_dropped():
    est = TimesyncEstimator(max_in_flight=2, max_delay_s=0.5)
    assert not est.reply(10_000, 999, 0)                 # answers no request of ours
    ts_old = est.request(1, 1.0)
    est.request(2, 1.1)
    est.request(3, 1.2)                                 # pushes the oldest out
    assert not est.reply(int(1.01e9), ts_old, 5)
    ts = est.request(4, 2.0)
    assert not est.reply(int(3.0e9), ts, 6)             # 1 s: implausible
    ts = est.request(5, 2.0)
    assert not est.reply(int(1.9e9), ts, 7)             # before the sample: impossible
    assert est.dropped == 4 and est.estimate() is None


def test_requests_are_paced_in_vehicle_time():
    est = TimesyncEstimator(request_period_s=0.1)
    assert est.due(5.0)
    est.request(0, 5.0)
    assert not est.due(5.05)
    assert est.due(5.1)
    assert est.due(1.0)          # vehicle clock went back (reboot): ask again


def test_the_estimate_follows_every_reply_and_is_not_recomputed_between_them():
    est = TimesyncEstimator(window=5)
    delays = [0.012, 0.020, 0.011, 0.030, 0.015, 0.013, 0.040]
    for k, d in enumerate(delays):
        t = 0.1 * (k + 1)
        ts1 = est.request(1_000_000 * k, t)
        assert est.reply(int(round((t + d) * 1e9)), ts1, 1_000_000 * k + 500_000)
        recent = np.array(delays[max(0, k - 4):k + 1])
        e = est.estimate()
        assert abs(e.delay_s - float(np.median(recent))) < 1e-12 and e.samples == len(recent)
        assert est.estimate() is e            # asked again before the next reply: the same object
