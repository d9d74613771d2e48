"""Planning errors name their cause in the user's terms: what, where, what to change."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.errors import ManeuverError
from mavreg.maneuver.diagnose import euler_singularity, explain_divergence
from mavreg.maneuver.plan import plan_spec

S = np.linspace(0.0, 10.0, 101)


def _where(q):
    return "loop" if q >= 5 else "run_up"


def _explain(pitch_deg=0.0, speed=5.0, rotors=(5.0, 6.0), curvature=0.1, at=7.0):
    f = np.tile(np.linspace(*rotors, 4), (len(S), 1))
    return explain_divergence(at, S, np.radians(np.full(len(S), pitch_deg)), np.full(len(S), speed),
                              f, 12.0, np.full(len(S), curvature), _where)


def test_each_cause_is_named_with_where_and_what_to_change():
    msg = _explain(pitch_deg=86)
    assert "s = 7.00 m in 'loop'" in msg and "singularity" in msg and "barrel roll" in msg
    assert "0.10 m/s" in _explain(speed=0.1) and "keep it above" in _explain(speed=0.1)
    assert "no authority" in _explain(rotors=(1.0, 11.9))
    assert "g of centripetal" in _explain(curvature=2.0, speed=8.0)
    assert "riccati_step_s" in _explain()          # nothing near a limit: the numerics
    assert _explain(pitch_deg=86).count(";") == 1  # one cause, not a list of guesses


def test_euler_singularity_only_near_ninety_degrees():
    assert euler_singularity(S, np.radians(np.full(len(S), 88.9)), _where) is None
    pitch = np.radians(np.where(S > 6, 89.5, 0.0))
    msg = euler_singularity(S, pitch, _where)
    assert "+89.5 deg at s = 6.10 m in 'loop'" in msg


def test_a_loop_flown_nose_first_is_refused_for_its_real_cause():
    """The issue's forward loop, the barrel roll file with heading 0 and yaw 0: with the yaw
    held, the nose reference crosses the thrust axis and the attitude flips (any attitude
    form); with the nose on the velocity, the paper's roll-pitch-yaw form is singular, and
    the message points at the SO(3) form. Never a Riccati step size."""
    text = maneuver_file("barrel_roll").read_text()
    text = text.replace("heading_deg: 270", "heading_deg: 0")
    for yaw, expected in (("", "the attitude flips by 180 deg"),
                          ("\n  mode: velocity", "roll-pitch-yaw attitude is singular")):
        spec = load_maneuver_text(text.replace("yaw:", "yaw:" + yaw, 1), "forward_loop.yaml")
        with pytest.raises(ManeuverError) as info:
            plan_spec(spec, load_vehicle(DEFAULT_VEHICLE), load_controller(PAPER_CONTROLLER))
        msg = str(info.value)
        assert expected in msg and "in 'loop'" in msg, msg
        assert "Riccati" not in msg and "reduce the step" not in msg
    assert "attitude_error: so3" in msg
