"""The emulator's delays in seconds (issue 31): ``--telemetry-delay-s`` and its kin reach the
link, the estimator and the rate loop; the ``-ms`` spellings of before are aliases for one
release that convert exactly and say so in one line; a bad value is refused in one line."""
from __future__ import annotations

import subprocess
import sys

import pytest

from firmware_sim import argtypes
from firmware_sim.cli import build_engine, build_parser
from mavreg import deprecated_options
from mavreg.cli import common

LISTEN = ["--listen", "udpin:127.0.0.1:0"]
NEW = ["--telemetry-delay-s", "0.02", "--telemetry-jitter-s", "0.009", "--command-delay-s", "0.013",
       "--command-jitter-s", "0.0026", "--estimate-latency-s", "0.007", "--rate-latency-s", "0.009"]
OLD = ["--telemetry-delay-ms", "20", "--telemetry-jitter-ms", "9", "--command-delay-ms", "13",
       "--command-jitter-ms", "2.6", "--estimate-latency-ms", "7", "--rate-latency-ms", "9"]


def _model(argv: list[str]) -> tuple:
    """What the engine built from ``argv`` flies with: the link lines' delays in ticks, the
    estimate's latency in physics steps (the history kept) and the rate loop's latency."""
    engine, _ = build_engine(build_parser().parse_args(LISTEN + argv))
    try:
        dl, ul = engine.downlink, engine.uplink
        return (dl.delay_periods, dl.jitter_periods, ul.delay_steps, ul.jitter_steps,
                len(engine.sim._history) - 1, engine.ap.rates.cfg.latency_s)
    finally:
        engine.link.close()


def test_the_seconds_reach_the_link_the_estimate_and_the_rate_loop():
    # 500 Hz control (telemetry) periods, 1 kHz physics steps
    assert _model(NEW) == (10.0, 4.5, 13.0, 2.6, 7, 0.009)
    assert _model([]) != _model(NEW)                          # negative control: the defaults differ


def test_an_old_ms_spelling_gives_the_same_doubles_and_warns_once_each(capsys):
    new = vars(build_parser().parse_args(LISTEN + NEW))
    assert capsys.readouterr().err == ""
    old = vars(build_parser().parse_args(LISTEN + OLD))
    err = capsys.readouterr().err.strip().splitlines()
    assert old == new                                         # bit for bit: == on the floats
    assert len(err) == 6
    for line, flag in zip(err, OLD[::2]):
        assert line == (f"firmware-sim: warning: {flag} is deprecated and goes in the next release; "
                        f"use {flag[:-3]}-s")
    assert _model(OLD) == _model(NEW)
    # negative control: milliseconds times 1e-3 are not these doubles (the reason the alias
    # converts in decimal)
    assert 9 * 1e-3 != 0.009 and 2.6 * 1e-3 != 0.0026 and 2.6 / 1000 == 0.0026


@pytest.mark.parametrize("argv", [["--telemetry-delay-s", "-0.001"], ["--command-jitter-s", "nan"],
                                  ["--estimate-latency-s", "1.5"], ["--rate-latency-s", "0.2"],
                                  ["--command-delay-s", "1e308"], ["--telemetry-delay-ms", "-1"],
                                  ["--command-jitter-ms", "inf"], ["--estimate-latency-ms", "1001"],
                                  ["--rate-latency-ms", "100.5"], ["--command-delay-ms", "x"]])
def test_a_bad_delay_is_refused_in_one_line_with_exit_2(argv):
    r = subprocess.run([sys.executable, "-m", "firmware_sim", *LISTEN, "--duration-s", "0.01", *argv],
                       capture_output=True, text=True, timeout=30)
    err = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(err) == 1 and err[0].startswith("firmware-sim: error:"), r.stderr
    assert argv[0] in err[0]


def test_the_bounds_are_those_of_before_in_seconds():
    """1000 ms for the link and the estimate, 100 ms for the rate loop: the edges pass."""
    args = build_parser().parse_args(["--telemetry-delay-s", "1", "--estimate-latency-ms", "1000",
                                      "--rate-latency-s", "0.1", "--rate-latency-ms", "100"])
    assert (args.telemetry_delay_s, args.estimate_latency_s, args.rate_latency_s) == (1.0, 1.0, 0.1)


def test_one_deprecated_alias_for_both_command_lines():
    assert argtypes.add_deprecated_alias is common.add_deprecated_alias is deprecated_options.add_deprecated_alias
    assert common.DeprecatedAlias is deprecated_options.DeprecatedAlias
    assert deprecated_options.scaled_text("20", "1e-3") == "0.020"
    assert deprecated_options.scaled_text(" 2.6", "1e-3") == "0.0026"
    for text in ("nan", "-inf", "x", ""):                    # left for the new option's type to refuse
        assert deprecated_options.scaled_text(text, "1e-3") == text


def test_whole_milliseconds_give_the_ticks_they_gave_in_ms():
    """The lines count ticks as ``delay_s * rate`` where they counted ``delay_ms * 1e-3 * rate``:
    the two products may differ in the last bit (9 ms), never in the rounded tick, for every
    whole millisecond to the 1 s bound at the control and physics rates a flight uses."""
    def ticks(x: float) -> int:                               # channel._ticks, engine's latency
        return int(x + 0.5)
    moved = [(ms, hz) for hz in (250, 500, 1000) for ms in range(0, 1001)
             if ticks(ms * 1e-3 * hz) != ticks(float(f"{ms}e-3") * hz)]
    assert moved == []
    assert 9 * 1e-3 * 1000 != 0.009 * 1000                   # the products do differ (control)
