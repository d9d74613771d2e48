"""A maneuver that ends going round its laps segment gets the periodic Riccati solution."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.errors import ManeuverError
from mavreg.maneuver.plan import plan_spec

RADIUS = 2.0
CIRCLE = f"""
kind: maneuver
version: 1
name: circle_laps
start: {{position_m: [0, 0, -3], heading_deg: 90}}
segments:
  - name: run_up
    line: {{length_m: 12}}
  - name: circle
    arc: {{radius_m: {RADIUS}, angle_deg: 360, bend_deg: 90}}
    blend_m: 4.0
speed:
  initial_m_s: 0.5
  changes:
    - {{segment: run_up, length_m: 8, to_m_s: 4.0}}
laps: {{segment: circle, count: 3}}
"""


@pytest.fixture(scope="module")
def params():
    return (load_vehicle(DEFAULT_VEHICLE),
            load_controller(PAPER_CONTROLLER))


def _gain_at(plan, s):
    return np.stack([np.interp(s, plan.s, plan.K[:, i, j]) for i in range(4) for j in range(11)])


def test_gains_repeat_lap_after_lap(params):
    plan = plan_spec(load_maneuver_text(CIRCLE), *params)
    assert plan.terminal.startswith("periodic")
    lap = 2 * np.pi * RADIUS
    s = np.linspace(plan.length_m - lap, plan.length_m, 40)
    k_last, k_prev = _gain_at(plan, s), _gain_at(plan, s - lap)
    scale = np.abs(plan.K).max()
    # The last lap ends on the periodic solution, so the lap before has the same gains (up
    # to the linear interpolation between grid nodes a few millimetres apart). The first
    # lap does not: its start is the blend from the run-up.
    assert np.abs(k_last - k_prev).max() < 2e-3 * scale
    # ...and they are not trivially constant: they vary around the lap.
    assert np.abs(k_last - k_last[:, :1]).max() > 1e-2 * scale


def test_non_periodic_last_lap_is_a_clear_error(params):
    # A speed change inside the last lap breaks the periodicity the terminal condition needs.
    text = CIRCLE.replace("laps: {segment: circle, count: 3}",
                          "laps: {segment: circle, count: 3}").replace(
        "    - {segment: run_up, length_m: 8, to_m_s: 4.0}",
        "    - {segment: run_up, length_m: 8, to_m_s: 4.0}\n"
        "    - {segment: circle, anchor: end, offset_m: 6.0, length_m: 5.0, to_m_s: 3.5}")
    with pytest.raises(ManeuverError, match="gain schedule: .*period"):
        plan_spec(load_maneuver_text(text), *params)
