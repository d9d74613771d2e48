"""The baseline's set-point schedule (mavreg.experiments.autopilot_baseline): the plan's nominal
in time, entered and left by the daemon's own ramps, consistent as a trajectory."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.paths import maneuver_file
from mavreg.experiments.autopilot_baseline import MANEUVER, BaselineSchedule, nominal_setpoint
from mavreg.planning.plan_io import plan_file
from harness.params import controller, vehicle


@pytest.fixture(scope="module")
def schedule():
    plan = plan_file(maneuver_file("figure_eight"), vehicle("ardupilot_freestyle"), controller("realistic"))
    return BaselineSchedule(plan, [0.0, 0.0, -0.2], 0.0, hold_s=2.0, exit_hold_s=2.0)


def test_phases_in_order_and_the_maneuver_is_the_plans_duration(schedule):
    names = [p.name for p in schedule.phases]
    assert names[:4] == ["spool", "climb", "transfer", "hold"] and names[-2:] == ["stop", "exit_hold"]
    start, end = schedule.maneuver_window_s
    assert end - start == pytest.approx(schedule.plan.duration_s, rel=2e-3)
    assert schedule.at(0.5 * (start + end)).phase == MANEUVER


def test_the_maneuver_starts_on_the_plans_entry_and_ends_on_its_exit(schedule):
    start, end = schedule.maneuver_window_s
    first = schedule.at(start)
    assert np.allclose(first.position_m, schedule.plan.x[0, :3], atol=1e-6)
    assert np.linalg.norm(first.velocity_m_s) == pytest.approx(schedule.plan.speed_m_s[0], rel=1e-3)
    assert np.allclose(nominal_setpoint(schedule.timed, end - start)[0], schedule.plan.x[-1, :3], atol=1e-3)


def test_position_velocity_acceleration_and_yaw_are_one_smooth_trajectory(schedule):
    h = 0.01
    t = np.arange(0.0, schedule.duration_s, h)
    sp = [schedule.at(float(ti)) for ti in t]
    p = np.array([s.position_m for s in sp])
    v = np.array([s.velocity_m_s for s in sp])
    a = np.array([s.accel_m_s2 for s in sp])
    assert np.abs(np.diff(p, axis=0) / h - 0.5 * (v[1:] + v[:-1])).max() < 0.01
    assert np.abs(np.diff(v, axis=0) / h - 0.5 * (a[1:] + a[:-1])).max() < 0.05
    yaw = np.array([s.yaw_rad for s in sp])
    rate = np.array([s.yaw_rate_rad_s for s in sp])
    assert np.abs(np.angle(np.exp(1j * np.diff(yaw))) / h - 0.5 * (rate[1:] + rate[:-1])).max() < 0.01
    assert np.linalg.norm(v, axis=1).max() == pytest.approx(4.5, abs=0.01)     # the profile's top speed
    assert np.linalg.norm(a, axis=1).max() == pytest.approx(4.5 ** 2 / 3.0, rel=0.02)   # on the 3 m circles


def test_bad_input_is_one_line():
    with pytest.raises(ValueError, match="hold_s must be a finite number"):
        BaselineSchedule(None, [0, 0, 0], 0.0, hold_s=-1.0)
    with pytest.raises(ValueError, match="start_m must be 3 finite"):
        BaselineSchedule(None, [0, 0], 0.0)


def test_the_thrust_feedforward_is_the_kinematic_one_less_the_nominals_drag(schedule):
    """On the freestyle file's drag (0.13 N s/m in the rotor plane, parasitic 0.027 N s2/m2):
    at the top speed the two differ by the drag's deceleration and agree at rest."""
    t = 0.5 * schedule.maneuver_s
    kin = nominal_setpoint(schedule.timed, t)
    thr = nominal_setpoint(schedule.timed, t, "thrust")
    drag = thr[2] - kin[2]                                  # what the thrust adds against the drag
    assert np.dot(drag, kin[1]) > 0                         # along the velocity
    assert 0.5 < np.linalg.norm(drag) < 2.0                 # (0.13 x 4.5 + 0.027 x 4.5^2) / 0.8 = 1.4 m/s2
    assert np.allclose(nominal_setpoint(schedule.timed, 0.0, "thrust")[2], nominal_setpoint(schedule.timed, 0.0)[2],
                       atol=0.15)
    with pytest.raises(ValueError, match="feedforward must be one of"):
        BaselineSchedule(schedule.plan, [0, 0, 0], 0.0, feedforward="jerk")
