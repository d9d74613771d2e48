"""The envelope monitor on synthetic signals: each bound fires when it must and not when it
must not (estimator-like noise, a real landing, the largest braking the rotors allow)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mavreg.config.envelope import EnvelopeParams
from mavreg.daemon.flight.monitor import EnvelopeMonitor, Tracking
from mavreg.daemon.flight.phases import Phase
from mavreg.model.rotation import rpy_to_matrix

MASS, FMAX, G = 0.749, 12.0, 9.81
DT = 0.002
LEVEL = np.eye(3)
HOVER_N = MASS * G / 4


def monitor(phase=Phase.MANEUVER, **env):
    m = EnvelopeMonitor(EnvelopeParams(**env), MASS, FMAX)
    m.set_origin((0.0, 0.0, 0.0))
    m.phase_changed(phase, 0.0)
    return m


def fly(m, phase, ts, ps, vs, Rs=None, rates=None, rotors=None, s=None):
    """Feed state samples (and optionally commands and tracking); first violation or None."""
    for k, t in enumerate(ts):
        R = LEVEL if Rs is None else Rs[k]
        w = np.zeros(3) if rates is None else rates[k]
        v = m.check_state(t, phase, math.nan if s is None else s[k], ps[k], vs[k], R, w)
        if v is not None:
            return v
        m.record_command(t, np.full(4, HOVER_N) if rotors is None else rotors[k])
    return None


def straight(t, p0, v):
    p0, v = np.asarray(p0, float), np.asarray(v, float)
    return p0 + np.outer(t, v), np.tile(v, (len(t), 1))


# ---------------------------------------------------------------- impact
def test_descent_into_the_ground_is_an_impact():
    t = np.arange(0, 0.5, DT)
    p, v = straight(t, (0, 0, -2.0), (0, 0, 5.0))           # 5 m/s down from 2 m
    got = fly(monitor(Phase.RECOVER), Phase.RECOVER, t, p, v)   # no altitude floor there
    assert got.bound == "impact" and got.impact
    assert -p[np.searchsorted(t, got.t_s), 2] <= 0.2 + 1e-9  # fired within 0.2 m of the ground


def test_a_landing_is_not_an_impact():
    """Descend at 0.3 m/s onto the ground and sit there (the emulator zeroes the velocity)."""
    t = np.arange(0, 3.0, DT)
    z = np.minimum(-0.4 + 0.3 * t, 0.0)
    vz = np.where(z < 0.0, 0.3, 0.0)
    p = np.column_stack([np.zeros_like(t), np.zeros_like(t), z])
    v = np.column_stack([np.zeros_like(t), np.zeros_like(t), vz])
    m = monitor(Phase.LAND)
    assert fly(m, Phase.LAND, t, p, v) is None
    assert m.peaks["impact_accel"]["ratio"] < 0.15


def test_stopped_dead_at_speed_in_the_air_is_a_spike_not_an_impact_and_the_hardest_braking_is_neither():
    """8 m/s to rest in one sample, 3 m up: an acceleration no rotor gives, but no ground
    contact: a violation (a recovery), never an impact (the motors are not stopped in the
    air). At the ground the speed bound calls it an impact first (test above)."""
    t = np.arange(0, 0.4, DT)
    p, v = straight(t, (0, 0, -3.0), (0, 8.0, 0))
    v[100:] = 0.0
    p[100:] = p[99]
    got = fly(monitor(), Phase.MANEUVER, t, p, v)
    assert got.bound == "accel_spike" and not got.impact and got.unit == "m/s^2" and got.value > 150.0
    # braking at the rotors' largest acceleration (4 fmax / m = 64 m/s^2) is not
    a = 4 * FMAX / MASS
    vy = np.maximum(8.0 - a * t, 0.0)
    v = np.column_stack([np.zeros_like(t), vy, np.zeros_like(t)])
    p = np.column_stack([np.zeros_like(t), np.cumsum(vy) * DT, np.full_like(t, -3.0)])
    assert fly(monitor(), Phase.MANEUVER, t, p, v) is None


def test_estimator_noise_fires_nothing():
    """30 s of hover with white velocity noise 2 cm/s and position noise 5 mm per sample
    (worse than a Gauss-Markov estimate of the same SD), 1 % of samples lost."""
    rng = np.random.default_rng(1)
    t = np.arange(0, 30.0, DT)
    keep = rng.random(len(t)) > 0.01
    t = t[keep]
    p = np.array([0.0, 0.0, -3.0]) + rng.normal(0, 0.005, (len(t), 3))
    v = rng.normal(0, 0.02, (len(t), 3))
    Rs = [rpy_to_matrix(*rng.normal(0, math.radians(0.3), 3)) for _ in t]
    rates = rng.normal(0, 0.005, (len(t), 3))
    m = monitor(Phase.HOLD)
    assert fly(m, Phase.HOLD, t, p, v, Rs, rates) is None
    worst = max(pk["ratio"] for pk in m.peaks.values())
    print(f"\nworst bound under estimator noise: {100 * worst:.0f} % of its limit")
    assert worst < 0.5


# ---------------------------------------------------------------- contradictions
def test_position_jump_fires_and_noise_and_gaps_do_not():
    t = np.arange(0, 1.0, DT)
    p, v = straight(t, (0, 0, -3.0), (0, 4.0, 0))
    p[300:, 0] += 0.5                                       # the estimate jumps 0.5 m north
    got = fly(monitor(), Phase.MANEUVER, t, p, v)
    assert got.bound == "position_jump" and 0.49 < got.value < 0.51 and not got.impact
    # a 0.3 s gap with consistent motion is not a jump
    keep = (t < 0.4) | (t > 0.7)
    p, v = straight(t, (0, 0, -3.0), (0, 4.0, 0))
    assert fly(monitor(), Phase.MANEUVER, t[keep], p[keep], v[keep]) is None


def test_full_thrust_while_falling_is_a_contradiction():
    """Rotors 1 and 3 at full thrust (24 N) while the telemetry shows a free fall."""
    t = np.arange(0, 1.0, DT)
    vz = 1.0 + G * t
    p = np.column_stack([np.zeros_like(t), np.zeros_like(t), -20.0 + t + 0.5 * G * t * t])
    v = np.column_stack([np.zeros_like(t), np.zeros_like(t), vz])
    cmd = np.tile([FMAX, 0.0, FMAX, 0.0], (len(t), 1))
    got = fly(monitor(), Phase.MANEUVER, t, p, v, rotors=cmd)
    assert got.bound == "thrust_mismatch" and not got.impact
    assert got.t_s >= EnvelopeParams().thrust_mismatch_s
    assert got.value < 0.05                                   # measured ~ 0 N of 24 N


def test_full_thrust_on_the_ground_is_an_impact():
    """The user's wreck: rotors 1 and 3 at full thrust, the vehicle lying still on the ground."""
    t = np.arange(0, 1.0, DT)
    p = np.zeros((len(t), 3))
    v = np.zeros((len(t), 3))
    cmd = np.tile([FMAX, 0.0, FMAX, 0.0], (len(t), 1))
    got = fly(monitor(Phase.LAND), Phase.LAND, t, p, v, rotors=cmd)
    assert got.bound == "thrust_mismatch" and got.impact


def test_heavier_vehicle_climbing_is_not_a_contradiction():
    """40 % heavier: the rotors give 1/1.4 of the acceleration the design mass predicts."""
    t = np.arange(0, 2.0, DT)
    cmd_total = 1.5 * MASS * G
    a_up = cmd_total / (1.4 * MASS) - G                      # true climb acceleration
    vz = -a_up * t
    p = np.column_stack([np.zeros_like(t), np.zeros_like(t), -3.0 + 0.5 * vz * t])
    v = np.column_stack([np.zeros_like(t), np.zeros_like(t), vz])
    m = monitor()
    assert fly(m, Phase.MANEUVER, t, p, v, rotors=np.full((len(t), 4), cmd_total / 4)) is None
    assert 0.6 < 1.0 / m.peaks["thrust_mismatch"]["ratio"] * 0.5 < 0.8   # measured/commanded ~ 0.71


# ---------------------------------------------------------------- where it may be
@pytest.mark.parametrize("phase,rate,fires", [(Phase.MANEUVER, 19.0, False), (Phase.MANEUVER, 21.0, True),
                                              (Phase.RECOVER, 25.0, False), (Phase.RECOVER, 31.0, True)])
def test_body_rate(phase, rate, fires):
    t = np.arange(0, 0.1, DT)
    p, v = straight(t, (0, 0, -5.0), (0, 0, 0))
    got = fly(monitor(phase), phase, t, p, v, rates=np.tile([rate, 0, 0], (len(t), 1)))
    assert (got is not None and got.bound == "body_rate") == fires


@pytest.mark.parametrize("phase,alt,fires", [(Phase.MANEUVER, 0.95, True), (Phase.HOLD, 1.05, False),
                                             (Phase.TAKEOFF, 0.5, False), (Phase.LAND, 0.5, False)])
def test_altitude_floor(phase, alt, fires):
    t = np.arange(0, 0.1, DT)
    p, v = straight(t, (0, 0, -alt), (0, 0, 0))
    got = fly(monitor(phase), phase, t, p, v)
    assert (got is not None and got.bound == "altitude_floor") == fires


@pytest.mark.parametrize("phase,north,up,fires", [(Phase.HOLD, 49.0, 5.0, False), (Phase.HOLD, 51.0, 5.0, True),
                                                  (Phase.MANEUVER, 0.0, 31.0, True),
                                                  (Phase.RECOVER, 55.0, 5.0, False), (Phase.RECOVER, 61.0, 5.0, True)])
def test_geofence_relative_to_the_take_off_point(phase, north, up, fires):
    m = monitor(phase)
    m.set_origin((100.0, -20.0, 2.0))                       # take-off point, NED
    t = np.arange(0, 0.1, DT)
    p, v = straight(t, (100.0 + north, -20.0, 2.0 - up), (0, 0, 0))
    got = fly(m, phase, t, p, v)
    assert (got is not None and got.bound == "geofence") == fires


# ---------------------------------------------------------------- tracking
def track(m, phase, ts, pos=0.0, att=0.0, rate=0.0, s=None, in_tube=None, clipped=None):
    for k, t in enumerate(ts):
        cmd = np.full(4, HOVER_N)
        if clipped is not None and clipped[k]:
            cmd[0] = FMAX + 1.0
        m.record_command(t, cmd)
        tr = Tracking(pos, att, rate, math.nan if s is None else s[k], True if in_tube is None else in_tube[k])
        v = m.check_tracking(t, phase, tr)
        if v is not None:
            return v
    return None


@pytest.mark.parametrize("phase", [Phase.TAKEOFF, Phase.HOLD, Phase.RUN_IN, Phase.MANEUVER, Phase.LAND])
def test_tracking_bounds_of_each_phase(phase):
    b = EnvelopeParams().bounds(phase)
    t = np.arange(0, 0.1, DT)
    s = 1.0 + 0.5 * t
    for name, kw, limit in (("position_error", "pos", b.max_position_error_m),
                            ("attitude_error", "att", b.max_attitude_error_rad),
                            ("rate_error", "rate", b.max_rate_error_rad_s)):
        assert track(monitor(phase), phase, t, s=s, **{kw: 0.95 * limit}) is None
        got = track(monitor(phase), phase, t, s=s, **{kw: 1.05 * limit})
        assert got.bound == name and got.phase == phase and got.limit == limit


def test_no_tracking_bounds_in_recovery():
    assert track(monitor(Phase.RECOVER), Phase.RECOVER, np.arange(0, 1, DT), pos=5.0, att=3.0, rate=10.0) is None


def test_tube_exit_must_last():
    t = np.arange(0, 0.2, DT)
    s = 1.0 + 2.0 * t
    short = (t >= 0.1) & (t < 0.14)
    assert track(monitor(), Phase.MANEUVER, t, s=s, in_tube=~short) is None
    got = track(monitor(), Phase.MANEUVER, t, s=s, in_tube=t < 0.1)
    assert got.bound == "tube" and got.t_s == pytest.approx(0.15, abs=1.5 * DT)


def test_progress_stuck_or_backwards_fires_slow_progress_does_not():
    stall = EnvelopeParams().max_stall_s                                     # 4 s
    t = np.arange(0, stall + 2.0, DT)
    assert track(monitor(), Phase.MANEUVER, t, s=0.2 * t) is None             # the slowest plans
    got = track(monitor(), Phase.MANEUVER, t, s=np.minimum(0.5 * t, 0.5))     # stuck from t = 1 s
    assert got.bound == "progress" and 0.9 + stall < got.t_s < 1.3 + stall
    got = track(monitor(), Phase.MANEUVER, t, s=np.where(t < 1, 0.5 * t, 1.0 - 0.3 * (t - 1)))
    assert got.bound == "progress" and got.value < 0
    # carried back for 1 s (a gust against a slow vehicle), then on again: not a stall, and
    # its peak is the time stalled against max_stall_s (about 1.2 s of 4), not an infinite ratio
    back = np.where(t < 1, 0.5 * t, np.where(t < 2, 0.5 - 0.8 * (t - 1), -0.3 + 0.5 * (t - 2)))
    m = monitor()
    assert track(m, Phase.MANEUVER, t, s=back) is None
    assert 0.2 < m.peaks["progress"]["ratio"] < 0.5


@pytest.mark.parametrize("phase,share,fires", [(Phase.MANEUVER, 0.4, False), (Phase.MANEUVER, 0.6, True),
                                               (Phase.HOLD, 0.1, False), (Phase.HOLD, 0.3, True)])
def test_saturation_share(phase, share, fires):
    t = np.arange(0, 1.0, DT)
    clipped = (np.arange(len(t)) % 10) < round(10 * share)
    got = track(monitor(phase), phase, t, s=1.0 + t, clipped=clipped)
    assert (got is not None and got.bound == "saturation") == fires
    if fires:
        assert got.t_s >= EnvelopeParams().saturation_window_s        # judged on a full window


def test_violation_reads_in_one_line():
    t = np.arange(0, 0.1, DT)
    got = track(monitor(), Phase.MANEUVER, t, s=12.3 + 0 * t, att=math.radians(40))
    line = got.describe()
    assert "\n" not in line and "attitude_error in maneuver at s=12.30 m" in line and "40 deg" in line


def test_window_search_selects_exactly_the_rows_a_full_filter_selects():
    """The bisection of the sliding windows against filtering every row (the old way), with
    now and then a row older than the one before it (a gap-filling command's time)."""
    from mavreg.daemon.flight.series import Series
    rng = np.random.default_rng(4)
    s = Series()
    rows = []                                       # every row kept, as the old deque held them
    t = 0.0
    for k in range(3000):
        t += float(rng.choice([0.002, 0.001, 0.004, 0.0021]))
        tr = t - 0.003 if k % 17 == 0 else t        # out of order now and then
        a, b = bool(rng.random() < 0.3), float(rng.uniform(0, 12))
        s.add(tr, a, b)
        rows.append((tr, a, b))
        s.drop_older(t, 0.5)
        rows = [r for r in rows if not t - r[0] > 0.5]
        assert sorted(rows, key=lambda r: r[0]) == list(zip(s.t[s.head:], s.a[s.head:], s.b[s.head:]))
        for w, strict in ((0.1, False), (0.5, True), (0.02, False), (0.002, True)):
            now = t + float(rng.choice([0.0, 0.002, 0.0005]))
            k0 = s.within(now, w, strict)
            want = sorted(r for r in rows if (now - r[0] < w if strict else now - r[0] <= w))
            assert sorted(zip(s.t[k0:], s.a[k0:], s.b[k0:])) == want
