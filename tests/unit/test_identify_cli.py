"""Reading a flight's .tlog for the calibration, and the ``mavreg identify`` command."""
from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink2

from tests.helpers.identify_synth import synthetic_flight, write_tlog
from mavreg.config.paths import DEFAULT_VEHICLE
from mavreg.cli.main import main
from mavreg.config.vehicle import load_vehicle
from mavreg.daemon.vehicle.messages import actuator_target, timesync_request
from mavreg.daemon.logs.tlog import TlogWriter
from mavreg.identify.flightlog import read_flight

VEH = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
DMN = mavlink2.MAVLink(None, srcSystem=1, srcComponent=191)


def _hb(armed, offboard):
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_PX4, 1 | (128 if armed else 0),
        (6 << 16) if offboard else (4 << 16) | (3 << 24), mavlink2.MAV_STATE_ACTIVE, 3).pack(VEH)


def _att(ms):
    return mavlink2.MAVLink_attitude_quaternion_message(ms, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0).pack(VEH)


def _pos(ms, vz=0.0):
    return mavlink2.MAVLink_local_position_ned_message(ms, 0.0, 0.0, -1.0, 0.0, 0.0, vz).pack(VEH)


def _cmd(usec, u, mav=DMN):
    return actuator_target(usec, 1, 1, [u] * 4).pack(mav)


def test_commands_are_paired_with_the_sample_they_answered(tmp_path):
    path = tmp_path / "f.tlog"
    with TlogWriter(path, clock_s=lambda: 1.7e9) as tl:
        for frame in [
            _hb(False, False), _att(0), _pos(0), _cmd(1_000, 0.1),          # sample 0 ms, answered
            _hb(True, True), _pos(2, 0.5), _att(2), _cmd(3_000, 0.2),       # parts in either order
            timesync_request(2_500_000).pack(DMN),                          # goes with the 2 ms sample
            _att(4),                                                        # 4 ms: position lost
            _cmd(5_000, 0.3),                                               # sent across the gap
            _att(2), _pos(2),                                               # a repeat: ignored
            _cmd(5_500, 0.9, mav=VEH),                                      # not the daemon's: ignored
            _att(6), _pos(6), _cmd(7_000, 0.4),
            mavlink2.MAVLink_timesync_message(20_000_000, 2_500_000).pack(VEH),   # reply at 20 ms
        ]:
            tl.write(frame)
    s = read_flight(path)
    assert s.t_s.tolist() == [0.0, 0.002, 0.006]
    assert s.controlled.tolist() == [False, True, True]
    assert s.velocity_ned_m_s[1, 2] == pytest.approx(0.5)
    # the gap command's daemon clock, less the paired ones' median offset (1 ms): 4 ms
    assert np.allclose(s.command_t_s, [0.0, 0.002, 0.004, 0.006])
    assert np.allclose(s.command_controls[:, 0], [0.1, 0.2, 0.3, 0.4], atol=1e-6)
    assert s.link_delay_s == pytest.approx(0.018)


def test_a_flight_directory_is_read_through_its_tlog(tmp_path):
    series = synthetic_flight(duration_s=1.0)
    (tmp_path / "flight").mkdir()
    write_tlog(series, tmp_path / "flight" / "flight.tlog")
    s = read_flight(tmp_path / "flight")
    assert s.t_s.size == series.t_s.size and np.allclose(s.command_t_s, series.t_s)
    assert np.allclose(s.velocity_ned_m_s, series.velocity_ned_m_s, atol=1e-5)
    assert s.link_delay_s == pytest.approx(0.018)


@pytest.mark.parametrize("make, words", [
    (lambda p: None, "no such file"),
    (lambda p: p.mkdir(), "no flight.tlog"),
    (lambda p: p.write_bytes(b"not a tlog at all\x00\x01"), "no vehicle telemetry"),
])
def test_unreadable_flights_are_one_line_errors(tmp_path, make, words):
    p = tmp_path / "x"
    make(p)
    with pytest.raises(ValueError) as e:
        read_flight(p)
    assert words in str(e.value) and "\n" not in str(e.value)


def test_a_tlog_without_commands_is_refused(tmp_path):
    path = tmp_path / "f.tlog"
    with TlogWriter(path) as tl:
        tl.write(_att(0))
        tl.write(_pos(0))
    with pytest.raises(ValueError, match="no rotor commands"):
        read_flight(path)


# ------------------------------------------------------------------ the command

@pytest.fixture(scope="module")
def flight_tlog(tmp_path_factory):
    path = tmp_path_factory.mktemp("identify") / "flight.tlog"
    write_tlog(synthetic_flight(duration_s=20.0, seed=3), path, link_delay_s=0.0135)
    return path


def test_identify_json_and_write_vehicle(flight_tlog, tmp_path, capsys):
    out = tmp_path / "calibrated.yaml"
    assert main(["identify", str(flight_tlog), "--json", "--write-vehicle", str(out)]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["delay_source"].startswith("TIMESYNC 13.5 ms")
    assert d["thrust_scale"]["value"] == pytest.approx(1.07, rel=0.005)
    assert d["drag_n_s_per_m"]["y"]["value"] == pytest.approx(0.35, rel=0.05)
    assert d["rotor_time_constant_s"]["value"] == pytest.approx(0.03, rel=0.1)
    lo, hi = d["thrust_scale"]["ci95"]
    assert lo <= 1.07 <= hi
    v = load_vehicle(out)
    assert v.thrust_scale == pytest.approx(d["thrust_scale"]["value"], abs=1e-4)
    assert v.rotor_time_constant_s == pytest.approx(d["rotor_time_constant_s"]["value"], abs=1e-4)
    assert v.rotor_drag_n_s_per_m[0] == pytest.approx(d["drag_xy_n_s_per_m"]["value"], abs=1e-4)
    assert v.rotor_drag_n_s_per_m[1] == pytest.approx(d["drag_n_s_per_m"]["z"]["value"], abs=1e-4)
    assert v.parasitic_drag_n_s2_per_m2 == 0.0
    # the emulator's rotors keep the lag they flew; the rest of its section is left alone
    original = load_vehicle(DEFAULT_VEHICLE)
    assert v.true_rotor_time_constant_s == original.true_rotor_time_constant_s == 0.02
    assert v.emulator == dataclasses.replace(original.emulator, true_rotor_time_constant_s=0.02)
    assert d["written"]["path"] == str(out)


def test_identify_prints_a_table(flight_tlog, capsys):
    assert main(["identify", str(flight_tlog), "--delay", "search", "--replicates", "100"]) == 0
    text = capsys.readouterr().out
    for words in ("thrust scale", "drag c_y (N s/m)", "rotor time constant (ms)", "searched jointly",
                  "moving-block bootstrap, 100 replicates", "R2"):
        assert words in text


def test_identify_help_explains_the_model(capsys):
    with pytest.raises(SystemExit) as e:
        main(["identify", "--help"])
    assert e.value.code == 0
    text = capsys.readouterr().out
    for words in ("FLIGHT", "thrust scale", "rotor", "--write-vehicle", "bootstrap", "TIMESYNC", "Exit status"):
        assert words in text


def _status(argv) -> int:
    """main()'s status, also when the argument parser refused the command line (SystemExit)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


@pytest.mark.parametrize("args, words", [
    (["/no/such/flight"], "no such file"),
    (["{empty}"], "no vehicle telemetry"),
    (["{flight}", "--write-vehicle", "/no/such/dir/v.yaml"], "no such directory"),   # before the fit
    (["{ground}"], "of usable flight"),
    (["{flight}", "--vehicle-params", "/no/such/vehicle.yaml"], "vehicle.yaml"),
])
def test_identify_bad_input_exits_2_with_one_line(tmp_path, flight_tlog, capsys, args, words):
    empty = tmp_path / "empty.tlog"
    empty.write_bytes(b"")
    ground = tmp_path / "ground.tlog"
    with TlogWriter(ground) as tl:       # a vehicle that never obeys: disarmed throughout
        tl.write(_hb(False, False))
        for k in range(3000):
            tl.write(_att(2 * k))
            tl.write(_pos(2 * k))
            tl.write(_cmd(2000 * k, 0.0))
    args = [a.format(empty=empty, flight=flight_tlog, ground=ground) for a in args]
    assert _status(["identify", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mavreg identify: error: ") and words in err[0]


def test_a_bad_option_value_exits_2(flight_tlog, capsys):
    with pytest.raises(SystemExit) as e:
        main(["identify", str(flight_tlog), "--delay", "soon"])
    assert e.value.code == 2
    assert "--delay: expected auto, timesync, search or a delay in ms" in capsys.readouterr().err
