"""One command-line dialect: the same concept has the same option name, unit and meaning in
every command of ``mavreg`` and in ``firmware-sim`` (docs/cli.md); the old spellings are
hidden aliases for one release that say so on stderr in one line."""
from __future__ import annotations

import argparse
from collections import defaultdict

import pytest

from firmware_sim.cli import build_parser as firmware_sim_parser
from mavreg.cli.common import PARAMS_DIR, Parser
from mavreg.cli.main import build_parser

BARREL = str(PARAMS_DIR / "maneuvers" / "barrel_roll.yaml")
VEHICLE = str(PARAMS_DIR / "vehicles" / "mk_quadro.yaml")

DIALECT = {
    # concept: (option, unit, the commands that take it)
    "vehicle parameter file": ("--vehicle-params", "YAML file",
                               {"plan", "simulate", "fly", "serve", "identify", "warm-up", "firmware-sim"}),
    "vehicle connection": ("--vehicle", "udpin:/udpout: URL", {"fly", "serve"}),
    "the vehicle's system id": ("--vehicle-system-id", "1..255", {"fly", "serve", "firmware-sim"}),
    "custom firmware's mode layout": ("--dialect", "px4 or ardupilot", {"fly", "serve"}),
    "controller file": ("--controller", "YAML file", {"plan", "simulate", "fly", "serve", "warm-up"}),
    "emulator world": ("--world", "preset name", {"fly", "firmware-sim"}),
    "control and telemetry rate": ("--control-rate-hz", "Hz", {"simulate", "fly", "serve", "warm-up",
                                                                "firmware-sim"}),
    "rotor force noise": ("--rotor-noise-sd-n", "N (SD)", {"simulate", "firmware-sim"}),
    "rotor force limit": ("--rotor-saturation-n", "N", {"simulate", "firmware-sim"}),
    "start off the entry": ("--entry-offset", "m, NED", {"simulate", "fly"}),
    "laps of the laps segment": ("--laps", "count", {"plan", "simulate", "fly", "upload"}),
    "plant inertia": ("--inertia-kg-m2", "kg m^2", {"simulate", "firmware-sim"}),
    "random seed": ("--seed", "integer", {"simulate", "identify", "experiment", "firmware-sim"}),
    "MAVLink 2 signing key": ("--signing-key", "file", {"fly", "serve", "firmware-sim"}),
    "lockstep": ("--lockstep", "flag", {"fly", "firmware-sim"}),
    "give up after": ("--timeout-s", "s (wall)", {"fly", "upload"}),
    "link lost after": ("--stale-timeout-s", "s (wall)", {"fly", "serve"}),
    "lockstep wait for a command": ("--lockstep-timeout-s", "s (wall)", {"firmware-sim"}),
    "offboard loss failsafe after": ("--offboard-loss-timeout-s", "s (sim)", {"firmware-sim"}),
    "control endpoint": ("--socket", "Unix socket path", {"fly", "serve", "upload"}),
    "output directory": ("--out", "directory", {"fly", "serve", "experiment"}),
    "JSON on stdout": ("--json", "flag", {"plan", "simulate", "identify"}),
    "gust window": ("--gust-window-s", "s (sim)", {"simulate"}),
    "lockstep speed while no commands stream": ("--lockstep-stall-factor", "x real time", {"firmware-sim"}),
    "telemetry delay": ("--telemetry-delay-s", "s (sim)", {"firmware-sim"}),
    "telemetry jitter": ("--telemetry-jitter-s", "s (sim)", {"firmware-sim"}),
    "command delay": ("--command-delay-s", "s (sim)", {"firmware-sim"}),
    "command jitter": ("--command-jitter-s", "s (sim)", {"firmware-sim"}),
    "estimate latency": ("--estimate-latency-s", "s (sim)", {"firmware-sim"}),
    "rate set-point latency": ("--rate-latency-s", "s (sim)", {"firmware-sim"}),
}
"""docs/cli.md's table. A command that gains one of these concepts takes this spelling."""

OTHER_SPELLINGS = {
    "vehicle parameter file": ("--vehicle-file", "--vehicle-yaml", "--params"),
    "emulator world": ("--preset", "--world-preset"),
    "control and telemetry rate": ("--rate-hz", "--rate", "--control-rate", "--telemetry-rate-hz"),
    "rotor force noise": ("--noise-n", "--noise", "--rotor-noise-n", "--noise-sd-n"),
    "rotor force limit": ("--saturation-n", "--saturation", "--rotor-limit-n"),
    "start off the entry": ("--offset", "--start-offset", "--entry-offset-m"),
    "lockstep wait for a command": ("--lockstep-timeout",),
    "offboard loss failsafe after": ("--offboard-loss-timeout",),
    "give up after": ("--timeout",),
    "the vehicle's system id": ("--system-id", "--sysid", "--target-system", "--vehicle-sysid"),
    "custom firmware's mode layout": ("--autopilot-dialect", "--mode-layout", "--modes"),
    "gust window": ("--gust-window",),
    "output directory": ("--tlog", "--control-log", "--out-dir", "--output-dir", "--outdir", "--dir"),
    "lockstep speed while no commands stream": ("--lockstep-stall-speed",),
    "telemetry delay": ("--telemetry-delay-ms", "--telemetry-delay"),
    "telemetry jitter": ("--telemetry-jitter-ms", "--telemetry-jitter"),
    "command delay": ("--command-delay-ms", "--command-delay"),
    "command jitter": ("--command-jitter-ms", "--command-jitter"),
    "estimate latency": ("--estimate-latency-ms", "--estimate-latency"),
    "rate set-point latency": ("--rate-latency-ms", "--rate-latency"),
}
"""Spellings a command must not show: the old ones (hidden aliases for a release) and near misses."""

ALIASES = [
    # (command, old spelling and value, new spelling and value)
    ("simulate", ["--offset", "0.6", "0", "-0.1"], ["--entry-offset", "0.6", "0", "-0.1"]),
    ("simulate", ["--noise-n", "0.1"], ["--rotor-noise-sd-n", "0.1"]),
    ("simulate", ["--saturation-n", "8.5"], ["--rotor-saturation-n", "8.5"]),
    ("simulate", ["--rate-hz", "500"], ["--control-rate-hz", "500"]),
    ("simulate", ["--gust-window", "1", "2"], ["--gust-window-s", "1", "2"]),
    ("firmware-sim", ["--lockstep-stall-speed", "0"], ["--lockstep-stall-factor", "0"]),
    ("firmware-sim", ["--vehicle", VEHICLE], ["--vehicle-params", VEHICLE]),
    ("firmware-sim", ["--rate-hz", "250"], ["--control-rate-hz", "250"]),
    ("firmware-sim", ["--preset", "ideal"], ["--world", "ideal"]),
    ("firmware-sim", ["--lockstep-timeout", "3"], ["--lockstep-timeout-s", "3"]),
    ("firmware-sim", ["--offboard-loss-timeout", "0.3"], ["--offboard-loss-timeout-s", "0.3"]),
    ("firmware-sim", ["--system-id", "6"], ["--vehicle-system-id", "6"]),
    # milliseconds to seconds, exactly in decimal: 9 * 1e-3 and 2.6 * 1e-3 are not the doubles
    # 0.009 and 0.0026, so a conversion by multiplication would fail the equality below
    ("firmware-sim", ["--telemetry-delay-ms", "20"], ["--telemetry-delay-s", "0.02"]),
    ("firmware-sim", ["--telemetry-jitter-ms", "9"], ["--telemetry-jitter-s", "0.009"]),
    ("firmware-sim", ["--command-delay-ms", "2.6"], ["--command-delay-s", "0.0026"]),
    ("firmware-sim", ["--command-jitter-ms", "13"], ["--command-jitter-s", "0.013"]),
    ("firmware-sim", ["--estimate-latency-ms", "1000"], ["--estimate-latency-s", "1"]),
    ("firmware-sim", ["--rate-latency-ms", "0"], ["--rate-latency-s", "0"]),
]


def _parsers() -> dict[str, argparse.ArgumentParser]:
    """Every command's parser, as the command line builds it."""
    _, modules = build_parser()
    out = {}
    for name, mod in modules.items():
        p = Parser(prog=f"mavreg {name}")
        mod.add_arguments(p)
        out[name] = p
    out["firmware-sim"] = firmware_sim_parser()
    return out


PARSERS = _parsers()
POSITIONAL = {"simulate": [BARREL]}


def _visible_options() -> dict[str, dict[str, argparse.Action]]:
    """option -> command -> Action, the options each --help shows (argparse keeps no public list)."""
    out: dict[str, dict[str, argparse.Action]] = defaultdict(dict)
    for cmd, p in PARSERS.items():
        for action in p._actions:
            if action.help == argparse.SUPPRESS:
                continue
            for opt in action.option_strings:
                if opt.startswith("--") and opt != "--help":
                    out[opt][cmd] = action
    return out


def test_each_concept_has_its_one_spelling_in_every_command_that_takes_it():
    shown = _visible_options()
    for concept, (option, _unit, commands) in DIALECT.items():
        assert set(shown.get(option, {})) == commands, (concept, option, sorted(shown.get(option, {})))


def test_no_command_shows_another_spelling_of_a_concept():
    shown = _visible_options()
    for concept, spellings in OTHER_SPELLINGS.items():
        for s in spellings:
            assert s not in shown, f"{sorted(shown[s])} spell {concept!r} {s}, not {DIALECT[concept][0]}"


def test_an_option_shared_by_commands_takes_the_same_values_in_each():
    """Same name, same meaning: the same count, choices, metavar (unit) and kind in every command
    (a YAML file in one and a URL in another was --vehicle's old fault)."""
    for option, by_cmd in _visible_options().items():
        shapes = {cmd: (a.nargs, tuple(a.choices or ()), a.metavar, type(a).__name__) for cmd, a in by_cmd.items()}
        assert len(set(shapes.values())) == 1, (option, shapes)


def _parse(cmd: str, argv: list[str]) -> argparse.Namespace:
    return PARSERS[cmd].parse_args(argv + POSITIONAL.get(cmd, []))


@pytest.mark.parametrize("cmd,old,new", ALIASES, ids=[f"{c} {o[0]}" for c, o, _ in ALIASES])
def test_an_old_spelling_still_works_for_a_release_and_says_so_in_one_line(cmd, old, new, capsys):
    with_new = _parse(cmd, new)
    assert capsys.readouterr().err == ""                     # the new spelling: no warning
    with_old = _parse(cmd, old)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "deprecated" in err[0] and old[0] in err[0] and new[0] in err[0], err
    assert vars(with_old) == vars(with_new)
    assert vars(_parse(cmd, [])) != vars(with_new)           # negative control: the value took effect


def test_an_old_spelling_is_hidden_from_help():
    for cmd, old, _ in ALIASES:
        assert old[0] + " " not in PARSERS[cmd].format_help().replace("\n", " ")


def test_a_bad_value_under_an_old_spelling_is_refused_as_under_the_new(capsys):
    for argv in (["--preset", "perfect"], ["--rate-hz", "0"]):
        with pytest.raises(SystemExit) as exc:
            _parse("firmware-sim", argv)
        assert exc.value.code == 2
    assert "invalid choice: 'perfect'" in capsys.readouterr().err


def _times_not_in_seconds(shown) -> list[str]:
    return sorted(o for o in shown if o.endswith(("-ms", "-us", "-min", "-millis", "-msec")))


def test_every_time_an_option_shows_is_in_seconds():
    """Issue 31: seconds everywhere, the unit in the name (the old -ms spellings are hidden
    aliases, tested above)."""
    assert _times_not_in_seconds(_visible_options()) == []
    p = Parser(prog="x")                                     # negative control: the check sees one
    p.add_argument("--telemetry-delay-ms")
    assert _times_not_in_seconds({o: None for a in p._actions for o in a.option_strings}) == ["--telemetry-delay-ms"]
