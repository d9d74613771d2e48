"""The YAML loader's errors: one line, FILE:LINE: KEY: what was expected."""
from __future__ import annotations

import argparse
import importlib.util
import math
import re
import subprocess
import sys

import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.loader import ConfigError, load_text
from mavreg.config.maneuver import load_maneuver, load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from tests.helpers.repo import ROOT

VEHICLE = DEFAULT_VEHICLE.read_text()
MANEUVER = maneuver_file("barrel_roll").read_text()


def _write(tmp_path, text, name="bad.yaml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def _line_of(text, needle):
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def _vehicle_error(tmp_path, text) -> ConfigError:
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError) as ei:
        load_vehicle(p)
    msg = str(ei.value)
    assert "\n" not in msg
    assert msg.startswith(str(p))
    return ei.value


def test_unknown_key_names_file_line_key_and_expected_keys(tmp_path):
    text = VEHICLE.replace("arm_length_m: 0.30", "arm_length_m: 0.30\narm_lenght_m: 0.30")
    err = _vehicle_error(tmp_path, text)
    line = _line_of(text, "arm_lenght_m")
    assert err.line == line
    assert err.key == "arm_lenght_m"
    msg = str(err)
    assert msg.startswith(f"{tmp_path / 'bad.yaml'}:{line}: arm_lenght_m: unknown key")
    for k in ("name", "mass_kg", "inertia_kg_m2", "arm_length_m", "drag_torque_ratio_m",
              "max_rotor_thrust_n", "emulator"):
        assert k in msg


def test_unknown_nested_key_has_dotted_path(tmp_path):
    text = VEHICLE.replace("crash_speed_m_s: 3.0", "crash_speed: 3.0")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "emulator.crash_speed"
    assert err.line == _line_of(text, "crash_speed:")
    assert "crash_speed_m_s" in str(err)


def test_missing_key(tmp_path):
    text = VEHICLE.replace("mass_kg: 0.749\n", "")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "mass_kg"
    assert "missing required key" in str(err)


def test_wrong_type(tmp_path):
    text = VEHICLE.replace("mass_kg: 0.749", "mass_kg: heavy")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "mass_kg" and err.line == _line_of(text, "mass_kg")
    assert "expected a number" in str(err) and "heavy" in str(err)


def test_wrong_vector_length(tmp_path):
    text = VEHICLE.replace("[0.0176, 0.0177, 0.034]", "[0.0176, 0.0177]")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "inertia_kg_m2" and "3 values" in str(err)


def test_negative_mass_is_out_of_range(tmp_path):
    text = VEHICLE.replace("mass_kg: 0.749", "mass_kg: -0.749")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "mass_kg" and err.line == _line_of(text, "mass_kg")
    assert "expected a value >= 0.01" in str(err) and "-0.749" in str(err) and "range [0.01, 100]" in str(err)


def test_physically_impossible_inertia_is_rejected(tmp_path):
    text = VEHICLE.replace("[0.0176, 0.0177, 0.034]", "[0.0176, 0.0177, 0.05]")
    err = _vehicle_error(tmp_path, text)
    assert "triangle inequality" in str(err)


def test_wrong_kind(tmp_path):
    text = VEHICLE.replace("kind: vehicle", "kind: maneuver")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "kind" and err.line == _line_of(text, "kind:")
    assert "'vehicle'" in str(err) and "'maneuver'" in str(err)


def test_wrong_version(tmp_path):
    text = VEHICLE.replace("version: 1", "version: 2")
    err = _vehicle_error(tmp_path, text)
    assert err.key == "version" and err.line == _line_of(text, "version:")
    assert "expected 1" in str(err)


def test_invalid_yaml_syntax(tmp_path):
    text = VEHICLE.replace("mass_kg: 0.749", "mass_kg: [0.749")
    err = _vehicle_error(tmp_path, text)
    assert "not valid YAML" in str(err)
    assert err.line is not None and re.match(rf"{re.escape(str(tmp_path / 'bad.yaml'))}:\d+: ", str(err))


def test_segment_with_two_shapes():
    text = MANEUVER.replace("line: {length_m: 18.0}",
                            "line: {length_m: 18.0}\n    arc: {radius_m: 2.0, angle_deg: 90}")
    with pytest.raises(ConfigError) as ei:
        load_maneuver_text(text, "two.yaml")
    msg = str(ei.value)
    assert msg.startswith(f"two.yaml:{_line_of(text, 'name: run_up')}: segments[0]:")
    assert "exactly one of line, arc, helix, waypoints" in msg and "line, arc" in msg


def test_unknown_segment_in_speed_changes():
    text = MANEUVER.replace("{segment: loop,", "{segment: lop,")
    with pytest.raises(ConfigError) as ei:
        load_maneuver_text(text, "ref.yaml")
    msg = str(ei.value)
    assert "no segment named 'lop'" in msg and "run_up, loop, run_out" in msg
    assert msg.startswith("ref.yaml:")


def test_unknown_shape_kind():
    text = MANEUVER.replace("line: {length_m: 18.0}", "spiral: {length_m: 18.0}")
    with pytest.raises(ConfigError) as ei:
        load_maneuver_text(text, "k.yaml")
    assert "segments[0].spiral" in str(ei.value) and "unknown key" in str(ei.value)


def test_deg_keys_are_converted_to_radians():
    spec = load_maneuver(maneuver_file("barrel_roll"))
    assert spec.start.heading_rad == pytest.approx(math.radians(270))
    loop = spec.segments[1].arc
    assert loop.angle_rad == pytest.approx(math.radians(400))
    assert loop.bend_rad == 0.0
    # the radian key itself is not accepted in YAML
    with pytest.raises(ConfigError, match="heading_rad: unknown key"):
        load_maneuver_text(MANEUVER.replace("heading_deg: 270", "heading_rad: 4.71"), "r.yaml")


def test_good_files_load():
    v = load_vehicle(DEFAULT_VEHICLE)
    assert v.mass_kg == 0.749 and v.inertia_kg_m2 == (0.0176, 0.0177, 0.034)
    c = load_controller(PAPER_CONTROLLER)
    assert len(c.q) == 11 and len(c.r) == 4


def _bad_maneuver(tmp_path):
    return _write(tmp_path, MANEUVER.replace("radius_m: 1.5", "radius_m: -1.5"), "bad_roll.yaml")


_CLI_COMPLETE = all(importlib.util.find_spec(f"mavreg.cli.{m}") is not None
                    for m in ("plan_cmd", "simulate_cmd", "fly_cmd", "serve_cmd", "upload_cmd"))


@pytest.mark.skipif(not _CLI_COMPLETE, reason="mavreg.cli.main imports fly/serve/upload modules "
                    "that are not written yet; see test_plan_command_bad_file_via_shim")
def test_mavreg_plan_on_bad_file_exits_2_with_one_line(tmp_path):
    p = _bad_maneuver(tmp_path)
    r = subprocess.run([sys.executable, "-m", "mavreg.cli.main", "plan", str(p)], cwd=ROOT,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1
    assert str(p) in lines[0] and "radius_m" in lines[0]


def test_plan_command_bad_file_via_shim(tmp_path):
    """The plan subcommand's run() on a bad file raises a ValueError (ConfigError) whose
    one-line message names the file, line and key; main() turns that into exit 2."""
    from mavreg.cli import plan_cmd
    parser = argparse.ArgumentParser()
    plan_cmd.add_arguments(parser)
    p = _bad_maneuver(tmp_path)
    args = parser.parse_args([str(p)])
    with pytest.raises(ValueError) as ei:
        plan_cmd.run(args)
    msg = str(ei.value)
    assert isinstance(ei.value, ConfigError)
    assert "\n" not in msg
    line = _line_of(p.read_text(), "radius_m: -1.5")
    assert msg.startswith(f"{p}:{line}: segments[1].arc.radius_m: expected a value > 0")


def test_a_number_in_exponent_notation_without_a_dot_is_a_number(tmp_path):
    """YAML 1.1 (PyYAML) resolves 1e-3 as a string; unquoted, the loader takes it as the
    number it says. Quoted, it stays a string and is refused."""
    from mavreg.config.controller import load_controller
    from mavreg.config.loader import ConfigError
    from mavreg.config.paths import PAPER_CONTROLLER
    text = PAPER_CONTROLLER.read_text().replace("riccati_step_s: 0.002", "riccati_step_s: 2e-3")
    f = tmp_path / "c.yaml"
    f.write_text(text)
    assert load_controller(f).riccati_step_s == 0.002
    f.write_text(text.replace("2e-3", '"2e-3"'))
    with pytest.raises(ConfigError, match="riccati_step_s: expected a number, got str"):
        load_controller(f)


VEHICLE_HEAD = """kind: vehicle
version: 1
name: v
mass_kg: 1.0
inertia_kg_m2: [0.02, 0.02, 0.03]
arm_length_m: 0.25
drag_torque_ratio_m: 0.016
max_rotor_thrust_n: 8.0
rotor_time_constant_s: 0.03
"""


def test_one_rotor_lag_key_which_the_emulated_rotors_follow_unless_told_otherwise():
    """The file's ``rotor_time_constant_s`` is the rotors' lag for the controller and the
    emulator; ``emulator.true_rotor_time_constant_s`` is a truth that differs (a mismatch)."""
    from mavreg.config.vehicle import VehicleParams
    v = load_text(VEHICLE_HEAD, VehicleParams, kind="vehicle")
    assert v.emulator.true_rotor_time_constant_s is None and v.true_rotor_time_constant_s == 0.03
    v = load_text(VEHICLE_HEAD + "emulator:\n  true_rotor_time_constant_s: 0.045\n", VehicleParams, kind="vehicle")
    assert (v.rotor_time_constant_s, v.true_rotor_time_constant_s) == (0.03, 0.045)


@pytest.mark.parametrize("old, new, value, read", [
    ("rotor_time_constant_s", "true_rotor_time_constant_s", "0.045", lambda v: v.true_rotor_time_constant_s),
    ("linear_drag_n_s_per_m", "linear_drag_xyz_n_s_per_m", "[0.3, 0.3, 0.6]",
     lambda v: v.emulator.linear_drag_xyz_n_s_per_m),
    ("parasitic_drag_n_s2_per_m2", "parasitic_drag_xyz_n_s2_per_m2", "[0.01, 0.01, 0.02]",
     lambda v: v.emulator.parasitic_drag_xyz_n_s2_per_m2)])
def test_a_renamed_key_is_read_for_one_release_with_a_warning_naming_the_new_one(old, new, value, read):
    from mavreg.config.vehicle import VehicleParams
    with pytest.warns(FutureWarning, match=rf"^f.yaml: line 11: emulator\.{old} is deprecated .*; write {new}$"):
        v = load_text(VEHICLE_HEAD + f"emulator:\n  {old}: {value}\n", VehicleParams, source="f.yaml", kind="vehicle")
    assert read(v) == read(load_text(VEHICLE_HEAD + f"emulator:\n  {new}: {value}\n", VehicleParams, kind="vehicle"))
    with pytest.raises(ConfigError, match=f"emulator.{old}: duplicate key"):      # both spellings
        load_text(VEHICLE_HEAD + f"emulator:\n  {new}: {value}\n  {old}: {value}\n", VehicleParams, kind="vehicle")
    with pytest.raises(ConfigError, match="unknown key"):                           # a typo is still refused
        load_text(VEHICLE_HEAD + f"emulator:\n  {old}x: {value}\n", VehicleParams, kind="vehicle")
