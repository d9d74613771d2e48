"""Tracking metrics on synthetic data with known answers."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mavreg.sim.metrics import tracking_metrics

SEGMENTS = [("run_up", 0.0, 10.0), ("loop", 10.0, 20.0)]


def synthetic():
    s = np.arange(0.0, 20.0 + 1e-9, 0.5)         # 41 samples: 20 in run_up, 21 in loop
    w = np.zeros((s.size, 11))
    run = s < 10.0
    w[run, 0], w[run, 1] = 0.3, 0.4              # 0.5 m off in the run-up
    w[~run, 0] = 0.01                            # 1 cm in the loop
    w[~run, 2] = np.radians(0.3)                 # 0.3 deg roll, 0.4 deg yaw: norm 0.5 deg
    w[~run, 4] = np.radians(0.4)
    w[s == 15.0, 3] = np.radians(-2.0)           # one pitch spike in the loop
    return s, w


def test_overall_and_per_segment_values():
    s, w = synthetic()
    m = tracking_metrics(s, w, SEGMENTS)
    assert m["samples"] == 41
    assert m["transverse_error_m"]["max"] == pytest.approx(0.5)
    assert m["transverse_error_m"]["rms"] == pytest.approx(np.sqrt((20 * 0.25 + 21 * 1e-4) / 41))
    run, loop = m["segments"]["run_up"], m["segments"]["loop"]
    assert (run["samples"], loop["samples"]) == (20, 21)
    assert (run["s_start_m"], run["s_end_m"], loop["s_start_m"], loop["s_end_m"]) == (0, 10, 10, 20)
    assert run["transverse_error_m"] == pytest.approx({"max": 0.5, "rms": 0.5})
    assert loop["transverse_error_m"] == pytest.approx({"max": 0.01, "rms": 0.01})
    assert run["attitude_error_deg"] == {"max": 0.0, "rms": 0.0}
    spike = np.sqrt(0.3 ** 2 + 2.0 ** 2 + 0.4 ** 2)
    assert loop["attitude_error_deg"]["max"] == pytest.approx(spike)
    assert loop["attitude_error_deg"]["rms"] == pytest.approx(np.sqrt((20 * 0.25 + spike ** 2) / 21))
    assert "rotor_command_n" not in m and "saturated_s" not in m
    json.dumps(m)                                # plain JSON types


def test_angles_are_wrapped():
    s = np.array([0.0, 1.0])
    w = np.zeros((2, 11))
    w[0, 2] = 2 * np.pi - np.radians(1.0)        # unwrapped: really -1 deg
    w[1, 4] = -2 * np.pi + np.radians(3.0)
    m = tracking_metrics(s, w, [("all", 0.0, 1.0)])
    assert m["attitude_error_deg"]["max"] == pytest.approx(3.0)
    assert m["segments"]["all"]["samples"] == 2   # s == last s_end is included


def test_rotor_forces_and_saturation_time():
    s, w = synthetic()
    f = np.full((s.size, 4), 5.0)
    f[s >= 12.0, 1] = 8.5                        # 17 samples at the limit, in the loop
    f[s == 3.0, 2] = 9.0                         # one beyond it, in the run-up
    f[s == 4.0, 3] = -0.5
    m = tracking_metrics(s, w, SEGMENTS, rotor_forces_n=f, max_rotor_thrust_n=8.5, dt_s=0.01)
    assert m["rotor_command_n"] == {"max": 9.0, "min": -0.5}
    assert m["saturated_samples"] == 18 and m["saturated_s"] == pytest.approx(0.18)
    assert m["segments"]["loop"]["saturated_s"] == pytest.approx(0.17)
    assert m["segments"]["run_up"]["saturated_s"] == pytest.approx(0.01)
    assert m["segments"]["run_up"]["rotor_command_n"] == {"max": 9.0, "min": -0.5}
    json.dumps(m)


def test_laps_merge_and_empty_and_outside_segments():
    s = np.array([-1.0, 0.5, 1.5, 2.5, 3.5, 9.0])
    w = np.zeros((6, 11))
    w[:, 0] = [7.0, 1.0, 2.0, 3.0, 4.0, 7.0]
    segs = [("loop", 0.0, 2.0), ("loop", 2.0, 4.0), ("exit", 4.0, 5.0)]
    m = tracking_metrics(s, w, segs)
    assert m["transverse_error_m"]["max"] == 7.0               # outside samples count overall
    loop = m["segments"]["loop"]
    assert loop["samples"] == 4 and (loop["s_start_m"], loop["s_end_m"]) == (0.0, 4.0)
    assert loop["transverse_error_m"]["max"] == 4.0
    assert m["segments"]["exit"]["samples"] == 0
    assert m["segments"]["exit"]["transverse_error_m"] is None
    json.dumps(m)


def test_bad_input():
    s, w = synthetic()
    with pytest.raises(ValueError, match="w must have shape"):
        tracking_metrics(s, w[:-1], SEGMENTS)
    with pytest.raises(ValueError, match="s_end"):
        tracking_metrics(s, w, [("x", 2.0, 1.0)])
    with pytest.raises(ValueError, match="dt_s"):
        tracking_metrics(s, w, SEGMENTS, rotor_forces_n=np.zeros((s.size, 4)), max_rotor_thrust_n=8.5)
    with pytest.raises(ValueError, match="non-empty"):
        tracking_metrics([], np.zeros((0, 11)), SEGMENTS)
