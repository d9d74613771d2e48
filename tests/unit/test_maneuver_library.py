"""The maneuver library (params/maneuvers/): every file plans feasible on the MK-Quadro at
12 N with the default controller, and loops flown nose-first plan across radius, speed,
bend and yaw mode wherever the rotors allow them."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from mavreg.config.paths import DEFAULT_VEHICLE, DESIGN_CONTROLLER, maneuver_files
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver, load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.errors import ManeuverError
from mavreg.maneuver.plan import plan_spec

VEHICLE = load_vehicle(DEFAULT_VEHICLE)
CONTROLLER = load_controller(DESIGN_CONTROLLER)
LIBRARY = maneuver_files()
NAMES = ("barrel_roll", "forward_loop", "split_s", "immelmann", "figure_eight",
         "climbing_helix", "slalom")


def test_the_library_has_the_seven_classics():
    assert sorted(p.stem for p in LIBRARY) == sorted(NAMES)


@pytest.mark.parametrize("path", LIBRARY, ids=[p.stem for p in LIBRARY])
def test_every_library_file_is_commented_and_plans_feasible(path):
    text = path.read_text()
    assert text.lstrip().startswith("#"), "each library file says what it flies and why"
    plan = plan_spec(load_maneuver(path), VEHICLE, CONTROLLER)
    lo, hi = plan.feasibility.rotor_force_n
    assert 0.0 <= lo and hi <= VEHICLE.max_rotor_thrust_n
    assert np.all(np.isfinite(plan.K)) and plan.attitude_error == "so3"


LOOP = """
kind: maneuver
version: 1
name: loop
start: {{position_m: [0.0, 0.0, -3.0], heading_deg: {heading}}}
segments:
  - {{name: run_up, line: {{length_m: 20.0}}}}
  - {{name: loop, arc: {{radius_m: {radius}, angle_deg: 360, bend_deg: {bend}}}, blend_m: 3.0}}
  - {{name: run_out, line: {{length_m: 12.0}}, blend_m: 3.0}}
speed:
  initial_m_s: 0.5
  changes:
    - {{segment: run_up, offset_m: 0.0, length_m: 12.0, to_m_s: {speed}}}
    - {{segment: loop, anchor: end, offset_m: 1.5, length_m: 10.0, to_m_s: 0.5}}
yaw: {{mode: {mode}}}
"""


def forward_loop(radius, speed, bend, mode, heading=0.0):
    return load_maneuver_text(LOOP.format(radius=radius, speed=speed, bend=bend, mode=mode,
                                          heading=heading), "loop.yaml")


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(radius=st.floats(1.5, 4.0), speed=st.floats(5.0, 9.0),
       bend=st.sampled_from([0.0, 90.0, -90.0]), heading=st.floats(0.0, 360.0).map(round),
       mode=st.sampled_from(["velocity", "tangent"]))
def test_a_loop_flown_nose_first_plans_wherever_the_rotors_allow_it(radius, speed, bend, heading, mode):
    """Feasible loops of any radius, speed, heading and bend (up: a loop through pitch
    +-90 deg, flown in yaw mode velocity; right or left: a level circle, either mode) plan in
    the SO(3) form; infeasible ones are refused for a rotor limit, never for the attitude."""
    if bend == 0.0:
        mode = "velocity"         # tangent is undefined where a loop's path is vertical
        speed = max(speed, np.sqrt(1.3 * 9.81 * radius))   # nose-first needs > 1 g at the top
    spec = forward_loop(radius, speed, bend, mode, heading)
    plan = plan_spec(spec, VEHICLE, CONTROLLER, strict=False)
    if plan.feasibility.feasible:
        full = plan_spec(spec, VEHICLE, CONTROLLER)
        assert np.all(np.isfinite(full.K))
        if bend == 0.0:
            assert np.degrees(np.abs(full.x[:, 4]).max()) > 80      # through the vertical
    else:
        assert all("rotor" in v or "speed" in v for v in plan.feasibility.violations)


def test_a_loop_too_slow_to_fly_nose_first_says_so():
    """Below sqrt(g r) at the top, the specific force lies along the velocity somewhere on
    the loop, and the nose cannot follow the velocity through it."""
    with pytest.raises(ManeuverError, match=r"in 'loop'.*sqrt\(g r\).*faster or wider"):
        plan_spec(forward_loop(3.0, 5.0, 0.0, "velocity"), VEHICLE, CONTROLLER)


def test_an_outside_loop_is_refused_with_its_place():
    """Bending down faster than gravity (12.5 m/s^2 here) asks the thrust to reverse
    through zero: no attitude is defined there, in any yaw mode."""
    with pytest.raises(ManeuverError, match=r"s = \d+\.\d+ m in '(run_up>loop|loop)'"):
        plan_spec(forward_loop(2.0, 5.0, 180.0, "velocity"), VEHICLE, CONTROLLER)


@pytest.mark.parametrize("mode", ["fixed", "tangent"])
def test_the_other_yaw_modes_name_why_a_loop_cannot_be_flown_nose_first(mode):
    """fixed: the nose reference meets the thrust axis (or the plan is infeasible);
    tangent: the path is vertical at the loop's sides. Each error names the place."""
    spec = forward_loop(2.0, 7.0, 0.0, mode)
    try:
        plan = plan_spec(spec, VEHICLE, CONTROLLER, strict=False)
    except ManeuverError as exc:
        assert "in 'loop'" in str(exc) or "in 'run_up>loop'" in str(exc)
        assert "yaw mode" in str(exc)
    else:
        assert not plan.feasibility.feasible


def _flies(plan):
    from mavreg.sim.maneuver_run import fly_on_design_model
    m = fly_on_design_model(plan).metrics
    assert m["status"] == "completed"
    assert m["transverse_error_m"]["max"] <= 0.01 and m["attitude_error_deg"]["max"] <= 1.0


@settings(max_examples=1, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(radius=st.floats(1.5, 3.0), g_at_top=st.floats(1.7, 2.4),
       heading=st.floats(0.0, 360.0).map(round))
def test_a_feasible_loop_flown_nose_first_flies_on_the_design_model(radius, g_at_top, heading):
    """From its nominal entry, through pitch +-90 deg: within 1 cm and 1 deg, wherever the
    rotors allow the loop."""
    speed = float(np.sqrt(g_at_top * 9.81 * radius))
    plan = plan_spec(forward_loop(radius, speed, 0.0, "velocity", heading), VEHICLE, CONTROLLER,
                     strict=False)
    assume(plan.feasibility.feasible)
    _flies(plan)


@pytest.mark.slow
@pytest.mark.parametrize("path", LIBRARY, ids=[p.stem for p in LIBRARY])
def test_every_library_maneuver_flies_on_the_design_model(path):
    _flies(plan_spec(load_maneuver(path), VEHICLE, CONTROLLER))
