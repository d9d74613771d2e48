"""`mavreg plan` checks the daemon's floor and geofence, as the daemon would before take-off."""
from __future__ import annotations

import json
from pathlib import Path

from mavreg.config.paths import maneuver_file
from mavreg.cli.main import main


def _plan(path: Path, capsys) -> tuple[int, dict]:
    code = main(["plan", str(path), "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_a_plan_above_the_geofence_ceiling_is_infeasible_with_the_cause(tmp_path, capsys):
    """forward_loop.yaml entered 40 m up climbs to 44 m: above the 30 m ceiling."""
    text = maneuver_file("forward_loop").read_text()
    assert "position_m: [0.0, 0.0, -3.0]" in text
    high = tmp_path / "high_loop.yaml"
    high.write_text(text.replace("position_m: [0.0, 0.0, -3.0]", "position_m: [0.0, 0.0, -40.0]"))
    code, d = _plan(high, capsys)
    assert code == 1 and not d["feasible"]
    assert d["envelope"]["bound"] == "gate_plan_geofence" and not d["envelope"]["inside"]
    assert any("geofence ceiling" in v and "44.0" in v for v in d["violations"])


def test_the_library_barrel_roll_is_inside_the_envelope(capsys):
    code, d = _plan(maneuver_file("barrel_roll"), capsys)
    assert code == 0 and d["envelope"]["inside"] and d["envelope"]["takeoff_point_ned_m"] == [0.0, 0.0, 0.0]
