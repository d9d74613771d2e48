"""Gust and lag metrics on known signals: a straight flight with a known excursion, the loop's centre."""
from __future__ import annotations

import math

import numpy as np
import pytest

from mavreg.experiments.definitions import RunSpec, gust
from mavreg.experiments.disturbance_metrics import (TUBE_M, along_track_speed, disturbance_metrics, loop_centre,
                                                    overspeed, peak_acceleration, time_above)
from mavreg.experiments.record import Flight, truth_trace
from mavreg.experiments.runner import plan_for
from mavreg.model.mixer import mixer_matrix
from mavreg.model.rotation import rpy_to_matrix


def test_time_above_a_ramp_is_where_it_crosses():
    t = np.linspace(0.0, 3.0, 3001)
    e = 0.25 * t                                    # above 0.5 from t = 2 on: 1 s
    assert time_above(t, e, 0.5) == pytest.approx(1.0, abs=1e-3)
    assert time_above(t, e, 1.0) == 0.0 and time_above(t[:1], e[:1], 0.0) == 0.0
    with pytest.raises(ValueError):
        time_above(t, e[:-1], 0.5)


def test_peak_acceleration_and_overspeed_of_known_signals():
    t = np.linspace(0.0, 2.0, 2001)
    v = np.stack([3.0 * np.sin(2.0 * t), np.zeros_like(t), np.ones_like(t)], axis=1)   # |a| <= 6
    assert peak_acceleration(t, v) == pytest.approx(6.0, rel=1e-5)
    # 0.3 m/s above a profile of 8 m/s where s > 10, nothing above the 1 m/s before
    s = np.linspace(0.0, 20.0, 5)
    assert overspeed([1.0, 1.0, 8.0, 8.3, 8.0], s, [0.0, 10.0, 20.0], [1.0, 8.0, 8.0]) == pytest.approx(0.3)


@pytest.fixture(scope="module")
def plan():
    exp = gust(0, forces_n=(8.0,), places=("run-up",), saturations_n=(None,))
    return plan_for(exp.maneuver_path, exp.vehicle_path, exp.controller_path, 1)


def test_the_loops_centre_is_1_5_m_from_every_point_of_the_loop(plan):
    c = loop_centre(plan.path, "loop")
    a, b = next((a, b) for n, a, b in plan.segments if n == "loop")
    pts = plan.path.evaluate(np.linspace(a, b, 50))[0]
    np.testing.assert_allclose(np.linalg.norm(pts - c, axis=1), 1.5, atol=1e-6)
    with pytest.raises(ValueError):
        loop_centre(plan.path, "no such segment")


def test_a_straight_flight_with_a_known_excursion(plan):
    """Along the run-up at its full 8 m/s, level, from s = 10 m to 16 m (0.75 s, where the
    blend into the loop begins), pushed north by d(t) = 0.8 sin(pi t / 0.75) and back: the
    distance, the time outside the tube and the acceleration are known, and it is never faster
    along the path than the profile."""
    T, A = 0.75, 0.8
    t = np.linspace(0.0, T, 751)
    w = math.pi / T
    d, dd, ddd = A * np.sin(w * t), A * w * np.cos(w * t), -A * w * w * np.sin(w * t)
    east0 = plan.path.point(10.0).position[1]
    pos = np.stack([d, east0 - 8.0 * t, np.full_like(t, -3.0)], axis=1)       # the run-up flies west at 3 m
    vel = np.stack([dd, np.full_like(t, -8.0), np.zeros_like(t)], axis=1)
    R = np.repeat(rpy_to_matrix(0.0, 0.0, 0.0)[None], t.size, axis=0)
    M = mixer_matrix(plan.vehicle.arm_length_m, plan.vehicle.drag_torque_ratio_m)
    rotors = np.tile(np.linalg.solve(M, plan.u[0]), (t.size, 1))
    flight = Flight(t, pos, R, vel, rotors, rotors, "timeout", "", False, None, {})
    spec = RunSpec(0, "known", controller="regulator", group="test", case="0.8 m", start_s_m=10.0)
    m = disturbance_metrics(plan, truth_trace(plan, flight), flight, spec)
    assert m["max_distance_m"] == pytest.approx(A, abs=1e-6)
    # d > 0.5 m while sin(w t) > 0.625: T - 2 asin(0.625) / w
    assert m["outside_tube_s"] == pytest.approx(T - 2 * math.asin(TUBE_M / A) / w, abs=2e-3)
    assert m["peak_acceleration_m_s2"] == pytest.approx(np.abs(ddd).max(), rel=1e-4)
    assert abs(m["overspeed_m_s"]) < 1e-6              # sideways is not faster along the path
    # the along-track speed: the run-up's tangent points west
    np.testing.assert_allclose(along_track_speed(plan.path, [10.0, 12.0], [[0.0, -8.0, 0.0], [3.0, 2.0, 1.0]]),
                               [8.0, -2.0], atol=1e-9)
    assert m["min_centre_distance_m"] is None                        # it never reached the loop
    # flown on into the loop (the nominal from s = 16 to 24 m): 1.5 m from its centre
    s2 = np.linspace(16.0, 24.0, 400)
    pos2 = np.array([plan.path.point(x).position for x in s2])
    on = Flight(np.arange(400) * 0.004, pos2, np.repeat(R[:1], 400, 0), np.zeros((400, 3)), rotors[:400],
                rotors[:400], "timeout", "", False, None, {})
    m2 = disturbance_metrics(plan, truth_trace(plan, on), on, spec)
    assert m2["min_centre_distance_m"] == pytest.approx(1.5, abs=1e-6)
    assert not m["completed"] and not m["diverged"] and not m["ok"] and m["late_s"] is None
    assert m["saturated_share"] == 0.0 and m["max_attitude_error_deg"] < 1e-6
