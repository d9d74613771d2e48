"""The torques-first allocation (mavreg.model.mixer.torques_first): roll and pitch are kept
exactly whenever some collective allows them, the collective is given up before them (the
yaw torque, 15.6 N of rotor difference per N m, gives way first), and every rotor force stays
within [0, F]."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.model.mixer import Mixer, torques_first, yaw_then_lift

MIX = Mixer(0.3, 0.016)
F = 7.0


def _wrench(f):
    return MIX.to_wrench(f)


def test_feasible_wrench_is_eq34_inverted_exactly():
    u = np.array([20.0, 0.4, -0.3, 0.02])
    f = MIX.to_rotors(u)
    assert f.min() > 0 and f.max() < F
    np.testing.assert_array_equal(torques_first(MIX.inverse, u, F), f)


def test_thrust_is_given_up_and_the_torques_kept_at_the_top():
    # 39 N and a roll torque of 0.9 N m, rotors of 7 N: the loop's bottom at 7 N
    u = np.array([39.0, 0.9, 0.0, 0.0])
    f = torques_first(MIX.inverse, u, F)
    w = _wrench(f)
    np.testing.assert_allclose(w[1:], u[1:], atol=1e-12)            # torques exact
    assert f.max() == pytest.approx(F, abs=1e-12) and f.min() >= 0.0
    # analytic: rotor 4 - rotor 2 = g1 / l = 3 N, rotors 1 and 3 equal; the largest (rotor 4) at F
    np.testing.assert_allclose(f, [F - 1.5, F - 3.0, F - 1.5, F], atol=1e-12)
    assert w[0] == pytest.approx(4 * F - 6.0)                        # 22 N of collective left
    # plain per-rotor clipping keeps more collective and loses the roll torque altogether
    clipped = np.clip(MIX.to_rotors(u), 0.0, F)
    np.testing.assert_allclose(clipped, [F, F, F, F])
    assert _wrench(clipped)[1] == pytest.approx(0.0)


def test_yaw_gives_way_before_the_collective_at_the_top():
    u = np.array([26.0, 0.3, 0.0, 0.05])
    assert MIX.to_rotors(u).max() > F
    f = torques_first(MIX.inverse, u, F)
    w = _wrench(f)
    assert f.max() <= F + 1e-12 and f.min() >= -1e-12
    assert w[1] == pytest.approx(0.3) and w[2] == pytest.approx(0.0, abs=1e-12)
    assert 0.0 <= w[3] < 0.05                                         # yaw reduced, same sign


def test_the_low_end_is_yaw_then_lift():
    # roll alone pulls a rotor: the collective is lifted, roll kept (as yaw_then_lift does)
    u = np.array([2.0, 1.0, 0.0, 0.05])
    np.testing.assert_allclose(torques_first(MIX.inverse, u, 12.0), yaw_then_lift(MIX.inverse, u, 12.0),
                               atol=1e-12)


def test_torques_that_do_not_fit_are_scaled_and_the_rotors_span_the_range():
    u = np.array([14.0, 3.0, 0.0, 0.0])                # g1 / l = 10 N of difference, F = 7 N
    f = torques_first(MIX.inverse, u, F)
    w = _wrench(f)
    assert f.min() == pytest.approx(0.0, abs=1e-12) and f.max() == pytest.approx(F)
    assert w[1] == pytest.approx(F * 0.3)                              # 2.1 N m: as much as there is
    assert w[2] == pytest.approx(0.0, abs=1e-12) and w[3] == pytest.approx(0.0, abs=1e-12)


def test_random_wrenches_stay_within_the_limits_and_keep_feasible_torques():
    rng = np.random.default_rng(3)
    for _ in range(2000):
        u = np.array([rng.uniform(0, 45), *rng.normal(0, [0.8, 0.8, 0.05])])
        f = torques_first(MIX.inverse, u, F)
        w = _wrench(f)
        assert f.min() >= -1e-9 and f.max() <= F + 1e-9
        g = MIX.to_rotors(np.array([0.0, u[1], u[2], 0.0]))   # roll and pitch's rotor differences
        if g.max() - g.min() <= F:                              # some collective allows them: kept
            np.testing.assert_allclose(w[1:3], u[1:3], atol=1e-9)
        if u[3] == 0.0 or np.all((MIX.to_rotors(u) >= 0) & (MIX.to_rotors(u) <= F)):
            continue
        # without yaw, the collective moves as little as the limits allow
        u0 = np.array([u[0], u[1], u[2], 0.0])
        if g.max() - g.min() <= F:
            c = np.clip(u0[0], -4 * g.min(), 4 * (F - g.max()))
            assert _wrench(torques_first(MIX.inverse, u0, F))[0] == pytest.approx(c, abs=1e-9)
