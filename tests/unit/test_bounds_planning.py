"""``mavreg plan`` on vehicle and controller files at the corners of their ranges (issue 32,
item 4): refused in one line or planned, never a traceback (exit 70).

A ``mass_kg`` of 1e-300 ended in scipy's ``ordqz`` ("the problem is very ill-conditioned")
and exit 70; the loader now refuses it (exit 2). Within the ranges, a 10 g airframe on the
design weights, or hover weights of 1e6 over 1e-6, ask the hover LQR for a loop faster than
10^4 rad/s: the margins refuse the plan in one line (exit 1). The per-field bounds are
tests/unit/test_param_bounds.py.
"""
from __future__ import annotations

import contextlib
import io

import pytest
import yaml

from mavreg.cli.main import main
from mavreg.config.paths import DESIGN_CONTROLLER, DEFAULT_VEHICLE, maneuver_file

BARREL = str(maneuver_file("barrel_roll"))


def _plan(tmp_path, vehicle: dict | None = None, controller: dict | None = None) -> tuple[int, str]:
    """``mavreg plan`` of the barrel roll on the bundled files with ``vehicle`` and
    ``controller`` keys replaced: (status, stderr)."""
    files = []
    for name, path, changes in (("v", DEFAULT_VEHICLE, vehicle), ("c", DESIGN_CONTROLLER, controller)):
        f = tmp_path / f"{name}.yaml"
        f.write_text(yaml.safe_dump({**yaml.safe_load(path.read_text()), **(changes or {})}, sort_keys=False))
        files.append(str(f))
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = main(["plan", BARREL, "--vehicle-params", files[0], "--controller", files[1]])
    return rc, err.getvalue()


def test_a_mass_of_1e_300_is_refused_in_one_line(tmp_path):
    rc, err = _plan(tmp_path, vehicle={"mass_kg": 1e-300})
    assert rc == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "v.yaml:" in err and "mass_kg: expected a value >= 0.01, got 1e-300 (range [0.01, 100])" in err


HOVER_TOO_FAST = "the hover LQR cannot be flown on this vehicle: the loop gain is still 1 or more at 10000 rad/s"
CORNERS = {     # (vehicle keys, controller keys, what stderr says: "" for nothing)
    "10 g on 2 cm arms": ({"mass_kg": 0.01, "arm_length_m": 0.02, "inertia_kg_m2": [1e-7] * 3,
                           "max_rotor_thrust_n": 0.05, "drag_torque_ratio_m": 5e-4}, None, HOVER_TOO_FAST),
    "100 kg on 2 m arms": ({"mass_kg": 100.0, "arm_length_m": 2.0, "inertia_kg_m2": [400.0] * 3,
                            "max_rotor_thrust_n": 500.0, "drag_torque_ratio_m": 0.2}, None, ""),
    "Q 1e6, R 1e-6": (None, {"q_position": [1e6] * 2, "q_attitude": [1e6] * 3, "q_velocity": [1e6] * 3,
                             "q_rate": [1e6] * 3, "r_input": [1e-6] * 4}, "the gain schedule diverged"),
    "hover Q 1e6, R 1e-6": (None, {"hover_q": [1e6] * 12, "hover_r_input": [1e-6] * 4}, HOVER_TOO_FAST),
}


@pytest.mark.parametrize("name", list(CORNERS))
def test_a_corner_of_the_ranges_plans_or_is_refused_in_one_line(name, tmp_path):
    vehicle, controller, says = CORNERS[name]
    rc, err = _plan(tmp_path, vehicle, controller)
    assert rc in (0, 1), (rc, err[:600])
    assert "Traceback" not in err and err.count("\n") <= 1, err[:600]
    if says:
        assert err.startswith("mavreg plan: error: ") and says in err and len(err) < 600, err
    else:
        assert not err, err
