"""Touchdown waits for the ground to stop the landing's descent (``touched_down``): an estimate's
height over the ground it took off from drifts (PX4's EKF2 follows its barometer, 0.3 m
measured), so the height alone may say "down" with the vehicle still in the air."""
from __future__ import annotations

import collections

import numpy as np

from mavreg.daemon.flight.hover_phases import touched_down
from mavreg.daemon.flight.phases import SupervisorParams

P = SupervisorParams()
DT = 0.005


def _land(height_m, vz_m_s):
    """Feed (t, vz, height) samples; the first touchdown as (t, speed), or None."""
    window = collections.deque()
    for k, (h, vz) in enumerate(zip(height_m, vz_m_s)):
        speed = touched_down(window, k * DT, float(vz), float(h), P)
        if speed is not None:
            return k * DT, speed
    return None


def _descent_onto_ground(ground_reads_m: float, v_m_s: float = 0.3, start_m: float = 1.0, t_end_s: float = 8.0):
    """A descent at ``v_m_s`` stopped by the ground, whose height the estimate reads as ``ground_reads_m``."""
    t = np.arange(0.0, t_end_s, DT)
    true_h = np.maximum(start_m - v_m_s * t, 0.0)
    vz = np.where(true_h > 0.0, v_m_s, 0.0)
    return true_h + ground_reads_m, vz, start_m / v_m_s


def test_a_descent_stopped_by_the_ground_is_a_touchdown_at_its_speed():
    h, vz, contact_s = _descent_onto_ground(0.0)
    t, speed = _land(h, vz)
    assert contact_s + P.touchdown_settle_s - 0.01 <= t <= contact_s + P.touchdown_settle_s + 0.02
    assert abs(speed - 0.3) < 1e-9


def test_an_estimate_that_reads_the_ground_high_or_low_still_lands_on_the_ground():
    for offset in (0.3, -0.3):           # EKF2's height 0.3 m off either way
        h, vz, contact_s = _descent_onto_ground(offset)
        t, _ = _land(h, vz)
        assert t >= contact_s, offset   # never before the ground stopped it


def test_negative_control_the_height_alone_would_have_idled_the_motors_in_the_air():
    """The estimate reads 0.3 m low: at its "zero" the vehicle is 0.3 m up and sinking; the
    height rule fired there, this one does not."""
    h, vz, contact_s = _descent_onto_ground(-0.3)
    first_low = int(np.argmax(h <= 0.03)) * DT
    assert first_low < contact_s - 0.9                        # the old rule: 1 s before the ground
    assert _land(h[: int(contact_s / DT)], vz[: int(contact_s / DT)]) is None


def test_a_landing_begun_low_is_not_a_touchdown_before_it_sinks():
    t = np.arange(0.0, 0.8, DT)
    assert _land(np.full(t.size, 0.3), np.zeros(t.size)) is None      # hovering at 0.3 m, not yet sinking


def test_above_the_band_a_stalled_descent_is_no_touchdown():
    t = np.arange(0.0, 3.0, DT)
    vz = np.where(t < 1.0, 0.3, 0.0)
    assert _land(np.full(t.size, P.touchdown_band_m + 0.2), vz) is None
