"""Every command's errors: an anticipated one is one line and exit 2 (bad input) or 1 (cannot be
flown); an unexpected exception is a bug (traceback, a request to report it, exit 70), never a
user error. Options and output paths are refused before any work (mavreg.errors, mavreg.cli)."""
from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER, maneuver_file
from mavreg.cli.main import BUG_REPORT, SUBCOMMANDS, main
from mavreg.errors import EXIT_BUG, EXIT_FAILED, EXIT_USAGE, ConfigError, ManeuverError, UsageError, exit_status_of

BARREL = str(maneuver_file("barrel_roll"))


def _run(argv) -> int:
    """main()'s status, also when the argument parser refused the command line."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _one_error_line(capsys, prog: str) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"mavreg {prog}: error: "), err
    return lines[0]


@pytest.mark.parametrize("argv, words", [
    (["simulate", BARREL, "--control-rate-hz", "0"], "--control-rate-hz: expected a number > 0"),          # was ZeroDivisionError
    (["simulate", BARREL, "--control-rate-hz", "300"], "1000 Hz divided by a whole number"),        # was a ValueError deep down
    (["simulate", BARREL, "--rotor-noise-sd-n", "nan"], "--rotor-noise-sd-n: expected a finite number"),
    (["simulate", BARREL, "--plot", "/no/such/dir/x.png"], "no such directory /no/such/dir"),  # was after 9 s
    (["simulate", BARREL, "--plot", "{tmp}"], "expected a file name ending in .png"),
    (["simulate", BARREL, "--seed", "-1"], "--seed: must be at least 0"),
    (["plan", "/no/such.yaml"], "/no/such.yaml: No such file or directory"),
    (["plan", "{tmp}"], "is a directory, not a file"),
    (["plan", "/dev/zero"], "/dev/zero: not a regular file"),
    (["plan", BARREL, "--controller", "{tmp}"], "--controller: "),
    (["plan", BARREL, "--laps", "0"], "--laps: must be at least 1"),
    (["fly", BARREL, "--out", "{file}"], "--out: {file}: exists and is not a directory"),
    (["fly", BARREL, "--vehicle", "udp:1"], "expected udpin:HOST:PORT, udpout:HOST:PORT, serial:PATH[:BAUD]"),
    (["fly", BARREL, "--timeout-s", "-1"], "--timeout-s: expected a number > 0"),
    (["fly", BARREL, "--vehicle-system-id", "0"], "--vehicle-system-id: must be at least 1, got 0"),
    (["fly", BARREL, "--vehicle-system-id", "256"], "--vehicle-system-id: a MAVLink system id is at most 255"),
    (["serve", "--vehicle-system-id", "six"], "--vehicle-system-id: expected a whole number, got 'six'"),
    (["fly", BARREL, "--dialect", "inav"], "--dialect: invalid choice: 'inav' (choose from 'px4', 'ardupilot')"),
    (["serve", "--dialect", "generic"], "--dialect: invalid choice: 'generic'"),
    (["fly", BARREL, "--vehicle-params", "{dialect}"], "dialect: expected one of px4, ardupilot, got 'inav'"),
    (["serve", "--out", "{file}"], "--out: {file}: exists and is not a directory"),
    (["serve", "--tlog", "/no/such/dir/f.tlog"], "--tlog: /no/such/dir/f.tlog: no such directory"),   # deprecated
    (["serve", "--control-log", "{tmp}"], "--control-log: {tmp}: is a directory"),
    (["serve", "--socket", "{file}/x.sock"], "is not a directory"),
    (["upload", "/no/such.yaml"], "No such file or directory"),
    (["identify", "{tmp}", "--write-vehicle", "/no/such/dir/v.yaml"], "no such directory"),
    (["experiment", "gust", "--out", "{file}"], "--out {file}: exists and is not a directory"),
], ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_bad_input_is_one_line_and_exit_2_before_any_work(argv, words, tmp_path, capsys):
    file = tmp_path / "a_file"
    file.write_text("")
    dialect = tmp_path / "dialect.yaml"               # a vehicle file with an unknown dialect
    dialect.write_text(DEFAULT_VEHICLE.read_text() + "\ndialect: inav\n")
    argv = [a.format(tmp=tmp_path, file=file, dialect=dialect) for a in argv]
    assert _run(argv) == EXIT_USAGE
    line = _one_error_line(capsys, argv[0])
    assert words.format(tmp=tmp_path, file=file) in line
    assert "planned" not in line


def test_upload_refuses_a_big_or_binary_file_before_connecting(tmp_path, capsys):
    big = tmp_path / "big.yaml"
    big.write_text("#" * (300 << 10))
    binary = tmp_path / "binary.yaml"
    binary.write_bytes(b"kind: \xff\xfe maneuver\n")
    nowhere = str(tmp_path / "no.sock")
    assert _run(["upload", str(big), "--socket", nowhere]) == EXIT_USAGE
    assert "a maneuver file is at most" in _one_error_line(capsys, "upload")
    assert _run(["upload", str(binary), "--socket", nowhere]) == EXIT_USAGE
    assert "not UTF-8 text" in _one_error_line(capsys, "upload")


def test_a_bad_key_in_a_file_is_exit_2_and_an_infeasible_maneuver_exit_1(tmp_path, capsys):
    text = open(BARREL).read()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("radius_m: 1.5", "radius_m: -1.5"))
    fast = tmp_path / "too_fast.yaml"
    fast.write_text(text.replace("to_m_s: 8.0", "to_m_s: 30.0"))
    assert _run(["simulate", str(bad)]) == EXIT_USAGE                # ConfigError
    assert "radius_m" in _one_error_line(capsys, "simulate")
    assert _run(["simulate", str(fast)]) == EXIT_FAILED              # ManeuverError: infeasible
    assert "is infeasible" in _one_error_line(capsys, "simulate")


def test_an_os_error_while_working_is_one_line_and_exit_2(monkeypatch, capsys):
    """A file that cannot be read once the command runs (as root nothing is unreadable, so
    the read is made to fail): ``PATH: reason``, not Python's ``[Errno 13]`` wording."""
    import mavreg.cli.plan_cmd as plan_cmd

    def unreadable(args):
        raise PermissionError(13, "Permission denied", "/secret/vehicle.yaml")
    monkeypatch.setattr(plan_cmd, "load_model_params", unreadable)
    assert _run(["plan", BARREL]) == EXIT_USAGE
    assert _one_error_line(capsys, "plan").endswith("error: /secret/vehicle.yaml: Permission denied")


@pytest.mark.parametrize("exc", [ValueError("operands could not be broadcast"), ZeroDivisionError("float division"),
                                 KeyError("s_m"), RecursionError("maximum recursion depth exceeded")])
def test_an_unexpected_exception_is_a_bug_with_a_traceback_and_exit_70(exc, monkeypatch, capsys):
    """The negative control of the old ``except ValueError``: a ValueError from numpy code is
    a bug, not the user's mistake."""
    import mavreg.cli.plan_cmd as plan_cmd

    def broken(args):
        raise exc
    monkeypatch.setattr(plan_cmd, "load_model_params", broken)
    assert _run(["plan", BARREL]) == EXIT_BUG
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and type(exc).__name__ in err
    assert err.strip().splitlines()[-1] == f"mavreg plan: {BUG_REPORT} (exit {EXIT_BUG})"


def test_the_anticipated_errors_and_their_statuses():
    assert exit_status_of(ConfigError("f.yaml", 3, "kind", "expected maneuver")) == EXIT_USAGE
    assert exit_status_of(UsageError("--x")) == EXIT_USAGE
    assert exit_status_of(ManeuverError("infeasible")) == EXIT_FAILED
    assert exit_status_of(FileNotFoundError(2, "No such file or directory", "x")) == EXIT_USAGE
    from mavreg.identify.regressors import IdentifyError
    assert exit_status_of(IdentifyError("only 3 samples")) == EXIT_USAGE
    for bug in (ValueError("x"), TypeError("x"), MemoryError(), RecursionError(), ZeroDivisionError()):
        assert exit_status_of(bug) is None
    assert isinstance(UsageError("x"), ValueError) and isinstance(ManeuverError("x"), ValueError)


@pytest.mark.parametrize("command", sorted(SUBCOMMANDS))
def test_every_help_ends_with_the_exit_statuses(command, capsys):
    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    out = capsys.readouterr().out
    assert exc.value.code == 0
    assert "exit status (every mavreg command" in out and "70   a bug in mavreg" in out


def _mavreg(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True,
                          timeout=120)


def test_as_a_process_bad_input_exits_2_and_a_bug_exits_70():
    r = _mavreg(f"""
        import sys
        from mavreg.cli.main import main
        sys.exit(main(["simulate", {BARREL!r}, "--control-rate-hz", "0"]))
    """)
    assert r.returncode == EXIT_USAGE and len(r.stderr.strip().splitlines()) == 1, r.stderr
    r = _mavreg(f"""
        import sys
        import mavreg.cli.plan_cmd as plan_cmd
        from mavreg.cli.main import main
        plan_cmd.load_model_params = lambda args: 1 / 0      # a bug
        sys.exit(main(["plan", {BARREL!r}]))
    """)
    assert r.returncode == EXIT_BUG and "ZeroDivisionError" in r.stderr and "bug in mavreg" in r.stderr


def test_firmware_sim_bad_flags_are_one_line_and_a_bug_is_a_traceback(monkeypatch, capsys, tmp_path):
    import firmware_sim.cli as fcli
    from firmware_sim.status import ExitCode
    for argv in (["--record", "/no/such/dir/x.npz"], ["--start", "z_m=5"], ["--listen", "udp:1"]):
        with pytest.raises(SystemExit) as exc:
            fcli.main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        assert exc.value.code == ExitCode.USAGE and len(err) == 1 and err[0].startswith("firmware-sim: error:")
    # a value only the validators refuse (jitter beyond delay): BadInput, one line
    assert fcli.main(["--telemetry-jitter-s", "0.05", "--listen", "udpin:127.0.0.1:0"]) == ExitCode.USAGE
    assert len(capsys.readouterr().err.strip().splitlines()) == 1

    def broken(*args, **kwargs):
        raise ValueError("a bug while building")
    monkeypatch.setattr(fcli, "Simulation", broken)
    assert fcli.main(["--listen", "udpin:127.0.0.1:0", "--duration-s", "0.01"]) == ExitCode.INTERNAL
    err = capsys.readouterr().err
    assert "Traceback" in err and "this is a bug in firmware_sim" in err


def test_fly_gives_2_for_a_bad_file_and_1_for_an_infeasible_maneuver():
    """``mavreg fly``'s maneuver is planned by the daemon's worker; its rejection keeps the
    status of the error behind it (the worker's PlanResult.status), before any link opens."""
    import asyncio

    from mavreg.config.controller import load_controller
    from mavreg.config.vehicle import load_vehicle
    from mavreg.daemon.jobs.app import Daemon, DaemonConfig, regulator_factory
    from mavreg.daemon.flight.supervisor import SupervisorParams
    from mavreg.errors import UserError
    vehicle_path, controller_path = DEFAULT_VEHICLE, PAPER_CONTROLLER
    vehicle = load_vehicle(vehicle_path)
    config = DaemonConfig("udpout:127.0.0.1:9", load_controller(controller_path), None, None, SupervisorParams())
    text = open(BARREL).read()
    statuses = []
    for bad in (text.replace("radius_m: 1.5", "radius_m: -1.5"), text.replace("to_m_s: 8.0", "to_m_s: 30.0")):
        daemon = Daemon(config, vehicle, regulator_factory(vehicle, 500.0), log=lambda line: None)
        with pytest.raises(UserError) as exc:
            asyncio.run(daemon.run([(bad, "f.yaml")], install_signals=False))
        assert daemon.link is None                       # refused before the link
        statuses.append(exit_status_of(exc.value))
    assert statuses == [EXIT_USAGE, EXIT_FAILED]
