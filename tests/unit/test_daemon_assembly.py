"""One assembly for ``fly`` and ``serve`` (mavreg/daemon/jobs/assembly.py): the same options
give the same daemon from either command; the options hold loaded objects, not paths beside
them; the files are loaded once; ``serve --out DIR`` is the output directory as in ``fly``,
and the old ``--tlog``/``--control-log`` still work for a release, with a warning."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import mavreg.daemon.jobs.app as daemon_app
from mavreg.cli.common import Parser
from mavreg.cli.main import build_parser
from mavreg.config.controller import ControllerParams, load_controller
from mavreg.config.paths import DEFAULT_VEHICLE, REAL_CONTROLLER, maneuver_file
from mavreg.config.vehicle import load_vehicle
from mavreg.daemon.flight.supervisor import SupervisorParams
from mavreg.daemon.jobs.assembly import DaemonOptions, EmulatorOptions
from mavreg.daemon.jobs.daemon_config import DaemonConfig
from mavreg.daemon.jobs.flight_book import NumberedFiles

BARREL = str(maneuver_file("barrel_roll"))
URL = "udpout:127.0.0.1:9"
SHARED = ["--vehicle", URL, "--control-rate-hz", "250", "--stale-timeout-s", "0.7", "--vehicle-lockstep",
          "--vehicle-system-id", "7", "--airborne", "fly", "--gcs", "udpout:127.0.0.1:14550",
          "--planner-cpu-s", "9", "--controller", str(REAL_CONTROLLER)]


class _Started(Exception):
    """Raised by the stand-in daemon in place of a flight."""


def _built(monkeypatch, argv: list[str]) -> dict:
    """What ``mavreg ARGV`` builds its daemon with (config, vehicle, kwargs), up to its run."""
    got = {}

    class Daemon:
        def __init__(self, config, vehicle, make_regulator=None, progress=None, **kwargs):
            got.update(config=config, vehicle=vehicle, make_regulator=make_regulator, **kwargs)
            self.progress = progress

        async def run(self, initial=(), timeout_s=None):
            got.update(initial=list(initial), timeout_s=timeout_s)
            raise _Started

    monkeypatch.setattr(daemon_app, "Daemon", Daemon)      # what assemble() builds
    parser, modules = build_parser()
    args = parser.parse_args(argv)
    with pytest.raises(_Started):
        modules[argv[0]].run(args)
    return got


def test_fly_and_serve_build_the_same_daemon_from_the_same_options(monkeypatch, tmp_path):
    sock = str(tmp_path / "s.sock")
    fly = _built(monkeypatch, ["fly", BARREL, *SHARED, "--out", str(tmp_path / "f"), "--socket", sock])
    serve = _built(monkeypatch, ["serve", *SHARED, "--once", "--out", str(tmp_path / "f"), "--socket", sock])
    assert fly["vehicle"] == serve["vehicle"] and fly["make_regulator"] is serve["make_regulator"] is None
    f, s = fly["config"], serve["config"]
    assert f.controller == s.controller == load_controller(REAL_CONTROLLER)
    assert (f.control_rate_hz, f.supervisor.stale_timeout_s, f.tlog_clock) == (250.0, 0.7, "vehicle")
    # what the commands mean to differ in, and nothing else: fly lands after its maneuver and
    # writes control.npz itself (with summary.json); serve holds and saves it per flight
    assert f.supervisor.land_when_done and not s.supervisor.land_when_done
    assert f.control_log_path is None and s.control_log_path == tmp_path / "f" / "control.npz"
    assert dataclasses.replace(s, control_log_path=None,
                               supervisor=dataclasses.replace(s.supervisor, land_when_done=True)) == f
    assert fly["initial"] == [(open(BARREL).read(), BARREL)] and serve["initial"] == []


def test_the_vehicle_and_controller_files_are_loaded_once(monkeypatch, tmp_path):
    import mavreg.config.controller as controller_mod
    import mavreg.config.vehicle as vehicle_mod
    calls = []
    for mod, name in ((vehicle_mod, "load_vehicle"), (controller_mod, "load_controller")):
        real = getattr(mod, name)
        monkeypatch.setattr(mod, name, lambda path, real=real, name=name: (calls.append(name), real(path))[1])
    _built(monkeypatch, ["fly", BARREL, "--vehicle", URL, "--out", str(tmp_path / "f")])
    assert sorted(calls) == ["load_controller", "load_vehicle"]
    calls.clear()
    _built(monkeypatch, ["serve", "--socket", str(tmp_path / "s.sock")])
    assert sorted(calls) == ["load_controller", "load_vehicle"]


def test_serve_out_holds_each_flights_tlog_and_controller_log(monkeypatch, tmp_path, capsys):
    out = tmp_path / "logs"
    c = _built(monkeypatch, ["serve", "--socket", str(tmp_path / "s.sock"), "--out", str(out)])["config"]
    assert (c.tlog_path, c.control_log_path, c.keep_control_log) == (out / "flight.tlog", out / "control.npz", True)
    assert NumberedFiles(c.tlog_path).path(2) == out / "flight-0002.tlog"
    assert capsys.readouterr().err.count("warning") == 0
    none = _built(monkeypatch, ["serve", "--socket", str(tmp_path / "s.sock")])["config"]
    assert (none.tlog_path, none.control_log_path, none.keep_control_log) == (None, None, False)


def test_the_old_tlog_and_control_log_still_work_for_a_release_and_say_so(monkeypatch, tmp_path, capsys):
    ctrl = tmp_path / "c.npz"
    c = _built(monkeypatch, ["serve", "--socket", str(tmp_path / "s.sock"), "--tlog", "/dev/full",
                             "--control-log", str(ctrl)])["config"]
    err = [ln for ln in capsys.readouterr().err.splitlines() if "warning" in ln]
    assert len(err) == 2 and all("deprecated" in ln and "--out DIR" in ln for ln in err)
    assert "--tlog" in err[0] and "--control-log" in err[1]
    assert (c.tlog_path, c.control_log_path, c.keep_control_log) == (Path("/dev/full"), ctrl, True)
    assert NumberedFiles(c.tlog_path).path(3) == Path("/dev/full")     # a device: written as given
    assert NumberedFiles(c.control_log_path).path(3) == tmp_path / "c-0003.npz"
    p = Parser(prog="mavreg serve")
    build_parser()[1]["serve"].add_arguments(p)
    assert "--tlog" not in p.format_help() and "--control-log" not in p.format_help()      # hidden


def test_the_options_hold_loaded_objects_not_paths():
    vehicle, controller = load_vehicle(DEFAULT_VEHICLE), load_controller(REAL_CONTROLLER)
    DaemonOptions(vehicle=vehicle, controller=controller, vehicle_url=URL)      # the rule's control
    DaemonConfig(URL, controller, None, None, SupervisorParams())
    with pytest.raises(TypeError, match="DaemonOptions.vehicle: a loaded VehicleParams"):
        DaemonOptions(vehicle=DEFAULT_VEHICLE, controller=controller, vehicle_url=URL)
    with pytest.raises(TypeError, match="DaemonOptions.controller: a loaded ControllerParams"):
        DaemonOptions(vehicle=vehicle, controller=REAL_CONTROLLER, vehicle_url=URL)
    with pytest.raises(TypeError, match="DaemonConfig.controller: a loaded ControllerParams"):
        DaemonConfig(URL, REAL_CONTROLLER, None, None, SupervisorParams())
    assert "controller_path" not in {f.name for f in dataclasses.fields(DaemonConfig)}
    assert isinstance(controller, ControllerParams)


def test_the_options_are_built_by_keyword_with_one_vehicle():
    vehicle, controller = load_vehicle(DEFAULT_VEHICLE), load_controller(REAL_CONTROLLER)
    with pytest.raises(TypeError):
        DaemonOptions(vehicle, controller, URL)          # the positional form is refused
    emulator = EmulatorOptions(vehicle_file=DEFAULT_VEHICLE, lockstep=True)
    opts = DaemonOptions(vehicle=vehicle, controller=controller, vehicle_url=None, emulator=emulator)
    assert opts.lockstep and not DaemonOptions(vehicle=vehicle, controller=controller, vehicle_url=URL).lockstep
    for url, emu in ((URL, emulator), (None, None)):     # a URL or the bundled emulator, exactly one
        with pytest.raises(ValueError, match="exactly one"):
            DaemonOptions(vehicle=vehicle, controller=controller, vehicle_url=url, emulator=emu)
