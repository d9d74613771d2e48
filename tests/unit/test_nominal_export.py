"""``mavreg plan --export``: the nominal as CSV and JSON, read back equal to the plan's arrays;
``--plot`` writes a small PNG; a file name it cannot write is refused before planning."""
from __future__ import annotations

import json

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, DESIGN_CONTROLLER
from mavreg.cli.main import main
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.maneuver.nominal_table import CSV_COLUMNS, nominal_table
from mavreg.planning.nominal_files import read_nominal_csv, write_nominal
from mavreg.planning.plan_io import plan_text
from mavreg.model.mixer import Mixer
from mavreg.model.rotation import quat_to_matrix

from harness.params import ONE_GATE as GATE


@pytest.fixture(scope="module")
def plan():
    return plan_text(GATE, "one_gate.yaml", load_vehicle(DEFAULT_VEHICLE), load_controller(DESIGN_CONTROLLER))


def _against_plan(plan, table) -> None:
    """The exported columns are the plan's own arrays (to the CSV's 12 digits)."""
    tol = dict(rtol=1e-10, atol=1e-10)
    assert np.allclose(table["s_m"], plan.s, **tol)
    assert np.allclose(table["position_ned_m"], plan.x[:, :3], **tol)
    assert np.allclose(table["body_rates_rad_s"], plan.x[:, 9:12], **tol)
    assert np.allclose(table["thrust_n"], plan.u[:, 0], **tol)
    assert np.allclose(table["torque_body_nm"], plan.u[:, 1:4], **tol)
    mixer = Mixer.from_vehicle(plan.vehicle)
    assert np.allclose(np.asarray(table["rotor_forces_n"]) @ mixer.matrix.T, plan.u, **tol)
    assert np.allclose(table["speed_m_s"], plan.speed_m_s, **tol)
    assert np.allclose(np.linalg.norm(table["velocity_ned_m_s"], axis=1), plan.speed_m_s, rtol=1e-8, atol=1e-9)
    for q, R in zip(np.asarray(table["quaternion_wxyz"])[::97], plan.R[::97]):
        assert np.allclose(quat_to_matrix(q), R, atol=1e-9)
    t = np.asarray(table["t_s"])
    assert t[0] == 0.0 and np.all(np.diff(t) > 0) and t[-1] == pytest.approx(plan.duration_s, rel=1e-9)
    assert np.all(np.diff(table["s_m"]) > 0)


def test_csv_round_trip(plan, tmp_path):
    path = write_nominal(plan, tmp_path / "nominal.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert tuple(header) == CSV_COLUMNS and all("_" in c for c in header)      # a unit in every name
    back = read_nominal_csv(path)
    _against_plan(plan, back)
    table = nominal_table(plan)
    for key, value in table.items():
        assert np.allclose(back[key], value, rtol=1e-10, atol=1e-10), key


def test_json_round_trip_units_in_keys(plan, tmp_path):
    doc = json.loads(write_nominal(plan, tmp_path / "nominal.json").read_text())
    assert doc["maneuver"] == "one_gate" and doc["rows"] == len(plan.s)
    assert [s["name"] for s in doc["segments"]] == ["run_up", "gate", "run_out"]
    _against_plan(plan, {k: np.asarray(v) for k, v in doc.items() if isinstance(v, list) and k != "segments"})
    units = ("_s", "_m", "_m_s", "_deg", "_rad_s", "_n", "_nm", "_wxyz")
    arrays = [k for k, v in doc.items() if isinstance(v, list) and k != "segments"]
    assert len(arrays) == 11 and all(k.endswith(units) for k in arrays)


def test_positions_lie_on_the_path(plan):
    table = nominal_table(plan)
    on_path = plan.path.evaluate(table["s_m"])[0]
    assert np.max(np.linalg.norm(table["position_ned_m"] - on_path, axis=1)) < 1e-6
    gate = table["position_ned_m"][np.argmax(table["position_ned_m"][:, 1])]
    assert gate[1] == pytest.approx(2.0, abs=0.1)          # the gate 2 m east is in the file


def test_cli_refuses_a_wrong_suffix_before_planning(tmp_path, capsys):
    # refused while the options are parsed: nothing is planned
    src = tmp_path / "gate.yaml"
    src.write_text(GATE)
    with pytest.raises(SystemExit) as exit_:
        main(["plan", str(src), "--export", str(tmp_path / "nominal.txt")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ".csv or .json" in err[0]


@pytest.mark.slow
def test_cli_writes_the_figure_and_the_export(tmp_path):
    """End to end through ``mavreg plan`` (10 s: the margins are computed too)."""
    src = tmp_path / "gate.yaml"
    src.write_text(GATE)
    png, csv = tmp_path / "plan.png", tmp_path / "plan.csv"
    assert main(["plan", str(src), "--plot", str(png), "--export", str(csv)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size < 200_000
    assert csv.read_text().splitlines()[0].startswith("t_s,s_m,north_m,east_m,down_m")
