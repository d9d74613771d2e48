"""The realistic world without sockets: delay lines, command timing, estimator statistics, presets."""
from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from mavreg.config.vehicle import load_vehicle
from firmware_sim.autopilot import Autopilot, AutopilotConfig
from firmware_sim.channel import Downlink, Uplink
from firmware_sim.engine import Engine
from firmware_sim.estimator import Estimator
from firmware_sim.link import Link
from firmware_sim.params import build_sim_params, default_vehicle_path, parse_start
from firmware_sim.physics import quat_mul
from firmware_sim.recorder import Recorder
from firmware_sim.sim import Simulation
from firmware_sim.stabilizer import Stabilizer
from firmware_sim.world import PRESETS, EstimatorParams, LinkParams, build_world

VEHICLE = load_vehicle(default_vehicle_path())


def decoded(msg, src=(1, 191)):
    return mavlink2.MAVLink(None).parse_buffer(msg.pack(mavlink2.MAVLink(None, *src)))[0]


def target(c):
    return decoded(mavlink2.MAVLink_set_actuator_control_target_message(0, 0, 1, 1, list(c) + [0.0] * 4))


def _state(tag):
    """Stand-ins for (ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED) of period ``tag``."""
    return (("att", tag), ("quat", tag), ("pos", tag))


def _release_delays(dl: Downlink, n: int, spacing: int, lo: int, hi: int) -> list:
    """Push ``n`` isolated bundles ``spacing`` periods apart; the delay (periods) of each."""
    delays = []
    for i in range(n):
        k = i * spacing
        dl.push_period(k, [], _state(i))
        assert not dl.release(k + lo - 1)[0], "released too early"
        for p in range(k + lo, k + hi + 1):
            msgs, _ = dl.release(p)
            if msgs:
                delays.append(p - k)
                break
        else:
            raise AssertionError("not released within the jitter window")
    return delays


# ------------------------------------------------------------------ delay lines
def test_downlink_delay_is_uniform_within_its_jitter():
    """10 +- 3 ms at a fine 0.1 ms period: mean, spread and bounds of a uniform delay."""
    dl = Downlink(LinkParams(telemetry_delay_s=0.010, telemetry_jitter_s=0.003), 10_000, 1, seed=11)
    d = np.array(_release_delays(dl, 20_000, 200, 70, 130)) * 0.1     # ms
    sd = 3.0 / math.sqrt(3.0)                                          # of U[-3, 3]
    assert abs(d.mean() - 10.0) < 4.5 * sd / math.sqrt(d.size)
    assert d.std() == pytest.approx(sd, rel=0.03)
    assert d.min() >= 7.0 and d.max() <= 13.0                          # within +-3 ms
    assert d.min() < 7.1 and d.max() > 12.9                            # and all of it used


def test_downlink_delay_is_quantized_to_the_control_period():
    """At 500 Hz, 10 +- 3 ms is 3.5..6.5 periods: released at the nearest boundary, 8/10/12 ms."""
    dl = Downlink(LinkParams(telemetry_delay_s=0.010, telemetry_jitter_s=0.003), 500, 2, seed=12)
    d = np.array(_release_delays(dl, 9000, 20, 4, 7)) * 2.0
    values, counts = np.unique(d, return_counts=True)
    assert values.tolist() == [8.0, 10.0, 12.0]
    n, p = d.size, 1 / 3
    assert np.all(np.abs(counts - n * p) < 4.5 * math.sqrt(n * p * (1 - p)))


def test_loss_rate_within_binomial_bounds_both_ways():
    p = 0.01
    dl = Downlink(LinkParams(loss_probability=p), 500, 2, seed=13)
    n_periods = 30_000
    complete = 0
    for k in range(n_periods):
        dl.push_period(k, [("hb", k)], _state(k))
        msgs, c = dl.release(k)
        complete += c
    n = 4 * n_periods
    assert abs(dl.lost - n * p) < 4.5 * math.sqrt(n * p * (1 - p))
    assert dl.sent + dl.lost == n
    # complete = quaternion and position both survived: probability (1 - p)^2
    q = (1 - p) ** 2
    assert abs(complete - n_periods * q) < 4.5 * math.sqrt(n_periods * q * (1 - q))
    up = Uplink(LinkParams(loss_probability=p), 1000, seed=13)
    n = 100_000
    kept = sum(up.push(i, ["cmd"], carries_target=i % 2 == 0) for i in range(n))
    assert kept + up.lost == n and abs(up.lost - n * p) < 4.5 * math.sqrt(n * p * (1 - p))


def test_downlink_is_fifo_release_is_max_of_previous_and_own_due_time():
    """Bundles every period with 10 +- 10 ms of jitter: never reordered, and held behind late ones.

    The expected release of each bundle is recomputed from the documented stream
    (``default_rng([seed, 2])``, one uniform per bundle for its delay).
    """
    seed, n = 21, 5000
    dl = Downlink(LinkParams(telemetry_delay_s=0.010, telemetry_jitter_s=0.010), 500, 2, seed)
    released = []
    for k in range(n + 20):
        if k < n:
            dl.push_period(k, [], _state(k))
        msgs, complete = dl.release(k)
        released.extend((k, m[1]) for m in msgs if m[0] == "pos")
    order = [tag for _, tag in released]
    assert order == list(range(n))                                   # FIFO
    u = np.random.default_rng([seed, 2]).random(n)
    due = [k + math.floor(5.0 + 5.0 * (2 * u[k] - 1) + 0.5) for k in range(n)]   # 10 ms = 5 periods
    expect = np.maximum.accumulate(due)
    assert [p for p, _ in released] == expect.tolist()
    assert sum(e > d for e, d in zip(expect, due)) > n // 4          # many were held back


def test_uplink_delay_statistics_and_fifo():
    up = Uplink(LinkParams(command_delay_s=0.005, command_jitter_s=0.003), 1000, seed=3)
    dues = []
    for i in range(20_000):
        step = 20 * i                                                 # isolated: no FIFO hold
        up.push(step, [i], carries_target=True)
        assert up.pop_due(step + 1) == []
        dues.append(up.next_due() - step)
        assert up.pop_due(dues[-1] + step) == [[i]]
    d = np.array(dues)
    assert set(d.tolist()) == {2, 3, 4, 5, 6, 7, 8}                 # 2..8 ms at 1 ms steps
    assert abs(d.mean() - 5.0) < 4.5 * 1.8 / math.sqrt(d.size)
    up = Uplink(LinkParams(command_delay_s=0.005, command_jitter_s=0.005), 1000, seed=4)
    for i in range(2000):
        up.push(i, [i], carries_target=False)
    got = [m[0] for m in up.pop_due(10_000)]
    assert got == list(range(2000))


# ------------------------------------------------------------------ engine timing
def make_engine(world, start="z_m=-20", recorder=None):
    p = build_sim_params(VEHICLE, 500, 1000, 0)
    sim = Simulation(p, parse_start(start) if start else None, recorder=recorder)
    v = p.vehicle
    stab = Stabilizer(v.mass_kg, p.inertia_matrix_kg_m2, v.arm_length_m, v.drag_torque_ratio_m,
                      v.max_rotor_thrust_n)
    ap = Autopilot(AutopilotConfig(max_rotor_thrust_n=v.max_rotor_thrust_n), stab, v.mass_kg * 9.81 / 4)
    if start:
        ap.start_in_flight(0.0)
    sim.record_initial(ap.armed, ap.mode)         # row i of a recording: the state after step i
    link = Link("udpin:127.0.0.1:0", 1, 1)        # no peers: sends nothing
    return Engine(sim, ap, link, world)


@pytest.mark.parametrize("delay_s, steps", [(0.003, 3), (0.0026, 3), (0.0004, 0), (0.0075, 8)])
def test_command_acts_at_the_physics_step_where_it_falls_due(tmp_path, delay_s, steps):
    rec = Recorder(tmp_path / "r.npz")
    world = build_world("ideal", command_delay_s=delay_s)
    eng = make_engine(world, recorder=rec)
    try:
        for _ in range(5):
            eng.begin_period()
            eng.step()
        n0 = eng.sim.step_count                                      # 10: received at t = 10 ms
        eng.receive([target([0.5] * 4)])
        for _ in range(6):
            eng.begin_period()
            eng.step()
    finally:
        eng.link.close()
    cmd = rec.data()[:, 14]                  # rotor 1 command of the step ending at row i
    first = int(np.argmax(cmd == 6.0))
    assert first - 1 == n0 + steps           # the step starting at n0 + steps uses it
    assert np.all(cmd[1:first] == pytest.approx(VEHICLE.mass_kg * 9.81 / 4))


def test_commands_and_timesync_go_through_the_same_delay():
    world = build_world("ideal", command_delay_s=0.005)
    eng = make_engine(world, start=None)
    replies = []
    eng.link.send = lambda msgs: replies.extend(msgs)
    try:
        eng.begin_period()
        eng.receive([decoded(mavlink2.MAVLink_command_long_message(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))])
        eng.receive([decoded(mavlink2.MAVLink_timesync_message(0, 42))])
        assert not eng.ap.armed
        eng.step()                                                   # 0..2 ms
        eng.begin_period()
        eng.step()                                                   # 2..4 ms
        assert not eng.ap.armed
        eng.begin_period()
        eng.step()                                                   # 4..6 ms: due at 5 ms
        assert eng.ap.armed
        eng.begin_period()                                           # replies go out at 6 ms
    finally:
        eng.link.close()
    sync = [m for m in replies if m.get_type() == "TIMESYNC"]
    assert [(m.tc1, m.ts1) for m in sync] == [(5_000_000, 42)]
    assert [m.result for m in replies if m.get_type() == "COMMAND_ACK"] == [0]


def test_ideal_world_publishes_the_truth_of_the_period(tmp_path):
    rec = Recorder(tmp_path / "r.npz")
    eng = make_engine(PRESETS["ideal"], start="z_m=-20,vx_m_s=3,r_deg_s=90", recorder=rec)
    try:
        for _ in range(50):
            eng.begin_period()
            eng.step()
    finally:
        eng.link.close()
    d, e = rec.data(), rec.estimate_data()
    k = np.rint(e[:, 0] * 1000).astype(int)                           # physics step = row
    assert np.array_equal(e[:, 1:4], d[k, 1:4]) and np.array_equal(e[:, 7:11], d[k, 4:8])


def test_estimate_describes_the_state_latency_earlier(tmp_path):
    """Hover while drifting north at 3 m/s and yawing at 90 deg/s: x = 3 t, yaw = pi/2 t."""
    rec = Recorder(tmp_path / "r.npz")
    world = build_world("realistic", estimator_scale=0.0)            # latency 4 ms, no errors
    eng = make_engine(world, start="z_m=-20,vx_m_s=3,r_deg_s=90", recorder=rec)
    try:
        for _ in range(100):
            eng.begin_period()
            eng.step()
    finally:
        eng.link.close()
    d, e = rec.data(), rec.estimate_data()
    t = e[:, 0]
    assert np.allclose(t, np.arange(100) * 0.002)
    lagged = np.clip(t - 0.004, 0.0, None)                            # before t = 0: the start
    assert np.allclose(e[:, 1], 3.0 * lagged, atol=1e-9)
    yaw = 2 * np.arctan2(e[:, 10], e[:, 7])
    assert np.allclose(yaw, math.pi / 2 * lagged, atol=1e-9)
    k = np.rint(lagged * 1000).astype(int)
    assert np.array_equal(e[:, 1:4], d[k, 1:4]) and np.array_equal(e[:, 7:11], d[k, 4:8])
    assert np.array_equal(e[:, 11:14], d[k, 11:14])


# ------------------------------------------------------------------ estimator statistics
def _ar1_bounds(a: float, n: int, lag: int) -> tuple[float, float]:
    """SD of the sample variance / variance and of the lag-``lag`` autocorrelation of an AR(1)."""
    r = (1 + a * a) / (1 - a * a)
    sd_var = math.sqrt(2.0 * r / n)
    sd_rho = math.sqrt(((1 + a * a) * (1 - a ** (2 * lag)) / (1 - a * a) - 2 * lag * a ** (2 * lag)) / n)
    return sd_var, sd_rho


def _autocorr(x: np.ndarray, lag: int) -> float:
    x = x - x.mean()
    return float(np.dot(x[:-lag], x[lag:]) / np.dot(x, x))


def test_gauss_markov_errors_have_their_sd_and_decorrelate_as_exp_minus_lag_over_tau():
    dt, lag = 0.002, 5
    tau = lag * dt                                   # the autocorrelation at lag tau is e^-1
    params = EstimatorParams(latency_s=0.0, position_sd_m=0.005, position_tau_s=tau,
                             velocity_sd_m_s=0.02, velocity_tau_s=tau, attitude_sd_deg=0.3,
                             attitude_tau_s=tau, gyro_noise_sd_rad_s=0.005, gyro_bias_sd_rad_s=0.003,
                             gyro_bias_tau_s=tau)
    est = Estimator(params, dt, seed=5)
    truth = (1.0, -2.0, -3.0, math.cos(0.4), 0.0, 0.0, math.sin(0.4), 0.5, 0.0, -0.2, 0.1, -0.3, 0.7)
    n = 200_000
    pos, vel, att, gyro = (np.empty((n, 3)) for _ in range(4))
    q_inv = (truth[3], -truth[4], -truth[5], -truth[6])
    for i in range(n):
        p, v, q, w = est.publish(truth)
        pos[i], vel[i], gyro[i] = p, v, w
        dq = quat_mul(q_inv, q)                      # body-frame error rotation
        att[i] = dq[1:4]
    pos -= truth[0:3]
    vel -= truth[7:10]
    gyro -= truth[10:13]
    att *= 2.0                                       # small angle: dtheta = 2 vec(dq)
    a = math.exp(-dt / tau)
    sd_var, sd_rho = _ar1_bounds(a, n, lag)
    for err, sd in ((pos, 0.005), (vel, 0.02), (att, math.radians(0.3))):
        for axis in range(3):
            x = err[:, axis]
            assert abs(x.var() / sd ** 2 - 1.0) < 4.5 * sd_var
            assert abs(_autocorr(x, lag) - math.exp(-1.0)) < 4.5 * sd_rho
            assert abs(x.mean()) < 4.5 * sd * math.sqrt((1 + a) / (1 - a) / n)
    # gyro: bias (Gauss-Markov) + white noise; only the bias is correlated at lag tau
    total = 0.003 ** 2 + 0.005 ** 2
    for axis in range(3):
        x = gyro[:, axis]
        assert x.var() / total == pytest.approx(1.0, abs=4.5 * sd_var)
        assert _autocorr(x, lag) == pytest.approx(0.003 ** 2 / total * math.exp(-1.0), abs=4.5 * sd_rho)
        assert abs(_autocorr(x, 1) - 0.003 ** 2 / total * a) < 4.5 * sd_rho


def test_estimator_scale_multiplies_every_error_sd():
    base = PRESETS["realistic"].estimator
    half = build_world("realistic", estimator_scale=0.5).estimator
    assert half.position_sd_m == 0.0025 and half.velocity_sd_m_s == 0.01
    assert half.attitude_sd_deg == 0.15 and half.gyro_noise_sd_rad_s == 0.0025
    assert half.gyro_bias_sd_rad_s == 0.0015 and half.latency_s == base.latency_s
    assert not build_world("realistic", estimator_scale=0).estimator.has_errors


# ------------------------------------------------------------------ presets
def test_presets_hold_the_documented_values_and_validate_overrides():
    r = PRESETS["realistic"]
    assert (r.link.telemetry_delay_s, r.link.telemetry_jitter_s, r.link.command_delay_s,
            r.link.command_jitter_s, r.link.loss_probability) == (0.010, 0.003, 0.005, 0.003, 0.01)
    e = r.estimator
    assert (e.latency_s, e.position_sd_m, e.position_tau_s, e.velocity_sd_m_s, e.velocity_tau_s,
            e.attitude_sd_deg, e.attitude_tau_s, e.gyro_noise_sd_rad_s, e.gyro_bias_sd_rad_s,
            e.gyro_bias_tau_s) == (0.004, 0.005, 0.5, 0.02, 0.2, 0.3, 0.5, 0.005, 0.003, 30.0)
    i = PRESETS["ideal"]
    assert i.link.ideal and not i.estimator.has_errors and i.estimator.latency_s == 0.0
    w = build_world("realistic", loss=0.0, command_delay_s=0.020)
    assert w.link.loss_probability == 0.0 and w.link.command_delay_s == 0.020
    assert w.overrides == (("--command-delay-s", 0.020), ("--loss", 0.0))
    for kwargs in ({"loss": 1.01}, {"loss": -0.1}, {"telemetry_delay_s": 0.002},
                   {"command_jitter_s": 0.006}, {"estimate_latency_s": math.inf},
                   {"estimator_scale": -1.0}, {"telemetry_delay_s": 1e3}, {"command_delay_s": 1.001}):
        with pytest.raises(ValueError, match="^--"):
            build_world("realistic", **kwargs)
    with pytest.raises(ValueError, match="--preset"):
        build_world("perfect")
