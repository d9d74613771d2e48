"""``--laps N`` means the same in plan, simulate, fly and upload: the maneuver file's laps
segment flown N times. fly and upload hand the daemon text, so the file's text is rewritten
(:func:`mavreg.config.maneuver.maneuver_text_with_laps`); a file without a laps segment, or
a count out of range, is one line and exit 2 before anything starts."""
from __future__ import annotations

from pathlib import Path

import pytest

import mavreg.daemon.jobs.endpoint as endpoint
import mavreg.daemon.jobs.app as daemon_app
from mavreg.cli.common import PARAMS_DIR
from mavreg.cli.main import build_parser, main
from mavreg.config.maneuver import load_maneuver, load_maneuver_text, maneuver_text_with_laps
from mavreg.errors import EXIT_USAGE

BARREL = PARAMS_DIR / "maneuvers" / "barrel_roll.yaml"
SLALOM = PARAMS_DIR / "maneuvers" / "slalom.yaml"      # no laps segment


def test_the_rewritten_text_is_the_file_with_its_laps_count_changed_and_nothing_else():
    text = BARREL.read_text()
    out = maneuver_text_with_laps(text, 3, str(BARREL))
    assert load_maneuver_text(out) == load_maneuver(BARREL).with_laps(3)
    assert load_maneuver_text(out) != load_maneuver(BARREL)                 # negative control
    with pytest.raises(ValueError, match="no 'laps' segment"):
        maneuver_text_with_laps(SLALOM.read_text(), 2, str(SLALOM))
    with pytest.raises(ValueError, match="1 to 100, got 101"):
        maneuver_text_with_laps(text, 101, str(BARREL))


@pytest.mark.parametrize("cmd", ["plan", "simulate", "fly", "upload"])
def test_a_maneuver_without_laps_is_a_usage_error_in_every_command(cmd, tmp_path, capsys):
    """Was a traceback and exit 70 in plan and simulate."""
    status = main([cmd, str(SLALOM), "--laps", "2", *(["--out", str(tmp_path / "o")] if cmd == "fly" else [])])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == EXIT_USAGE and len(err) == 1 and "--laps 2" in err[0] and "laps" in err[0], err
    assert not (tmp_path / "o").exists()


class _Started(Exception):
    """Raised by the stand-in daemon in place of a flight."""


def _fly_until_the_daemon_starts(monkeypatch, tmp_path, argv) -> list:
    """``mavreg fly`` up to the daemon's run; returns the maneuvers it was handed."""
    handed = []

    class Daemon:
        def __init__(self, config, *args, progress=None, **kwargs):
            from mavreg.progress import Progress
            self.config = config
            self.progress = progress if progress is not None else Progress(quiet=True)

        async def run(self, initial, timeout_s=None):
            handed.extend(initial)
            raise _Started

    monkeypatch.setattr(daemon_app, "Daemon", Daemon)     # what assemble() builds
    parser, modules = build_parser()
    args = parser.parse_args(["fly", str(BARREL), "--vehicle", "udpout:127.0.0.1:9", "--out", str(tmp_path), *argv])
    with pytest.raises(_Started):
        modules["fly"].run(args)
    return handed


def test_fly_plans_the_maneuver_with_its_laps(monkeypatch, tmp_path):
    [(text, source)] = _fly_until_the_daemon_starts(monkeypatch, tmp_path, ["--laps", "3"])
    assert source == str(BARREL) and load_maneuver_text(text).laps.count == 3
    [(text, _)] = _fly_until_the_daemon_starts(monkeypatch, tmp_path, [])
    assert text == BARREL.read_text()                 # without --laps: the file as it is


def test_upload_sends_the_maneuver_with_its_laps(monkeypatch, capsys):
    sent = []

    def request(path, req, timeout_s):
        sent.append(req)
        return {"ok": True, "detail": "queued"}

    monkeypatch.setattr(endpoint, "request", request)
    assert main(["upload", str(BARREL), "--laps", "4", "--socket", "/nonexistent/s"]) == 0
    assert main(["upload", str(BARREL), "--socket", "/nonexistent/s"]) == 0
    assert load_maneuver_text(sent[0]["yaml"]).laps.count == 4
    assert sent[1]["yaml"] == Path(BARREL).read_text()
    assert main(["upload", "--land", "--laps", "2"]) == EXIT_USAGE
    assert "--laps needs a maneuver FILE" in capsys.readouterr().err
