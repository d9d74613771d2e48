"""``mavreg plan FILE`` prints the margins ``mavreg fly FILE`` flies with (issue 31): plan and
simulate default to the files fly and serve use, and the margins plan prints are those of the
plan the daemon makes, in its own planner worker, from what ``fly FILE`` hands it."""
from __future__ import annotations

import asyncio
import json

import pytest

import mavreg.daemon.jobs.app as daemon_app
from mavreg.cli.main import build_parser, main
from mavreg.cli.plan_cmd import format_margins
from mavreg.config.paths import REAL_CONTROLLER, maneuver_file
from mavreg.daemon.jobs.planner_pool import PlannerPool

BARREL = maneuver_file("barrel_roll")


def _defaults(command: str) -> tuple[str, str]:
    parser, _ = build_parser()
    extra = ["--vehicle", "udpout:127.0.0.1:9"] if command == "serve" else [str(BARREL)]
    args = parser.parse_args([command, *extra])
    return args.vehicle_params, args.controller


def test_every_command_that_plans_defaults_to_the_files_fly_flies():
    fly = _defaults("fly")
    assert fly[1] == str(REAL_CONTROLLER)
    for command in ("plan", "simulate", "serve", "warm-up"):
        assert _defaults(command) == fly, command


class _Started(Exception):
    """Raised by the stand-in daemon in place of a flight."""


def _what_fly_hands_the_daemon(monkeypatch, tmp_path) -> tuple:
    """``mavreg fly BARREL`` up to the daemon: (vehicle, controller, [(text, source)])."""
    got = {}

    class Daemon:
        def __init__(self, config, vehicle, make_regulator=None, progress=None, **kwargs):
            from mavreg.progress import Progress
            got.update(vehicle=vehicle, controller=config.controller)
            self.progress = progress if progress is not None else Progress(quiet=True)

        async def run(self, initial, timeout_s=None):
            got["initial"] = list(initial)
            raise _Started

    monkeypatch.setattr(daemon_app, "Daemon", Daemon)     # what assemble() builds
    parser, modules = build_parser()
    args = parser.parse_args(["fly", str(BARREL), "--vehicle", "udpout:127.0.0.1:9", "--out", str(tmp_path)])
    with pytest.raises(_Started):
        modules["fly"].run(args)
    return got["vehicle"], got["controller"], got["initial"]


def _planned_by_the_daemon(vehicle, controller, text: str, source: str):
    """The plan the daemon's planner worker (a spawned process) returns for an upload."""
    async def plan():
        pool = PlannerPool(vehicle, controller)
        try:
            return await pool.plan(text, source)
        finally:
            pool.shutdown()
    result = asyncio.run(plan())
    assert result.accepted, result.reason
    return result.plan


def test_plan_prints_the_margins_of_the_plan_fly_flies(monkeypatch, tmp_path, capsys):
    vehicle, controller, [(text, source)] = _what_fly_hands_the_daemon(monkeypatch, tmp_path)
    flown = _planned_by_the_daemon(vehicle, controller, text, source).margins.as_dict()
    assert main(["plan", str(BARREL)]) == 0
    printed = capsys.readouterr().out
    for line in format_margins(flown):         # the same two lines, to the printed digit
        assert line in printed, (line, printed)
    assert main(["plan", str(BARREL), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["margins"] == flown      # and every figure
    assert flown["maneuver"]["delay_margin_ms"] > 20     # realistic.yaml's, not design.yaml's 1.7 ms
