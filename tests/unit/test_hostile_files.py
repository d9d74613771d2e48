"""Hostile maneuver files: each gives ``mavreg plan FILE`` one line on stderr and exit 2,
quickly and in bounded memory (issue 21; docs/reliability.md, "Hostile files").

The corpus is tests/data/hostile/ (written by its generate.py); the big cases are made here
in tmp_path: a 100 MB file, /dev/zero, 100 000 waypoints, 100 000-deep nesting. Most files
run through the CLI's ``main`` in this process (fast); the worst few run as subprocesses,
whose peak memory (``RUSAGE_CHILDREN`` of a small wrapper process, so that this process's
own size does not count: generate.run_measured) must stay under 300 MB. Their times are
printed, not asserted (the machine is shared).
"""
from __future__ import annotations

import contextlib
import importlib.util
import io
import warnings
from pathlib import Path

import pytest

from mavreg.config.paths import DESIGN_CONTROLLER, maneuver_file
from mavreg.cli.main import main

HOSTILE = Path(__file__).resolve().parents[1] / "data" / "hostile"
_spec = importlib.util.spec_from_file_location("hostile_generate", HOSTILE / "generate.py")
GEN = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(GEN)
CORPUS = sorted(HOSTILE.glob("*.yaml"))
BARREL = maneuver_file("barrel_roll")
DESIGN = DESIGN_CONTROLLER
MAX_STDERR_CHARS = 600
MAX_RSS_MB = 300


def _assert_one_line(rc, err: str) -> None:
    assert rc == 2, (rc, err[:300])
    assert err.endswith("\n") and err.count("\n") == 1, err[:300]
    assert "Traceback" not in err and err.startswith("mavreg plan: error: "), err[:300]
    assert len(err) <= MAX_STDERR_CHARS, len(err)


def _plan_here(*args: str) -> tuple[int, str]:
    """``mavreg plan ARGS`` through the CLI's main in this process: (status, stderr). A warning
    (which the real CLI would print on stderr) fails the test."""
    out, err = io.StringIO(), io.StringIO()
    with warnings.catch_warnings(record=True) as caught, \
            contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        warnings.simplefilter("always")
        try:
            rc = main(["plan", *args])
        except SystemExit as exc:           # refused while parsing the options
            rc = exc.code
    assert not caught, [str(w.message) for w in caught]
    return rc, err.getvalue()


def test_the_corpus_is_there():
    assert len(CORPUS) >= 80
    assert all(p.stat().st_size < 64 * 1024 for p in CORPUS)


@pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])
def test_each_corpus_file_gives_one_line_and_exit_2(path):
    _assert_one_line(*_plan_here(str(path)))


# -- every required key of the barrel roll missing in turn ---------------------------------

MISSING = GEN.missing_key_cases()


def test_the_required_keys_are_found():
    """Negative control of the generator: the keys it removes include the nested ones."""
    names = {".".join(map(str, p)) for p in GEN.required_key_paths()}
    assert {"name", "start.position_m", "segments.1.arc.radius_m", "segments.0.line",
            "speed.changes.1.to_m_s", "laps.segment"} <= names
    assert "limits.min_speed_m_s" not in names and "yaw.initial_deg" not in names


@pytest.mark.parametrize("name", list(MISSING))
def test_each_required_key_missing_gives_one_line(name, tmp_path):
    f = tmp_path / "missing.yaml"
    f.write_text(MISSING[name])
    rc, err = _plan_here(str(f))
    _assert_one_line(rc, err)
    assert name.rsplit(".", 1)[-1].split()[-1] in err or "exactly one of" in err


# -- the big cases, made at test time -------------------------------------------------------

IN_PROCESS = ["startup (a missing file)", "100 MB file", "100 000 waypoints (2 MB)",
              "60 000 waypoints (compact, under 1 MiB)", "riccati_step_s 1e-9",
              "riccati_step_s 1e-4 (budget)"]
SUBPROCESS = ["alias bomb (kind:)", "/dev/zero", "100 000-deep nesting", "--laps 100"]


def test_the_big_cases_in_process(tmp_path):
    cases = GEN.big_cases(tmp_path)
    assert set(IN_PROCESS + SUBPROCESS) == set(cases)
    for name in IN_PROCESS:
        rc, err = _plan_here(*cases[name])
        _assert_one_line(rc, err)


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hostile")
    cases = GEN.big_cases(tmp)
    return {name: GEN.run_measured(cases[name], tmp) for name in SUBPROCESS}


def test_the_worst_cases_give_one_line_in_a_subprocess(measured):
    for name, (rc, err, _, _) in measured.items():
        assert rc == 2 and err.count("\n") == 1, (name, rc, err[:300])
        _assert_one_line(rc, err)


def test_the_worst_cases_stay_under_300_mb(measured):
    """Peak RSS of each worst case's process; the times are reported (-s), not asserted
    (benchmarks/hostile_files.py measures every case, and the cost of starting the CLI)."""
    for name, (_, _, seconds, rss_mb) in measured.items():
        print(f"hostile: {name}: {seconds:.2f} s, {rss_mb:.0f} MB")
    worst = max(measured.items(), key=lambda kv: kv[1][3])
    assert worst[1][3] <= MAX_RSS_MB, worst


def test_the_budget_names_its_cause(tmp_path):
    """Laps, step and length each named, with how many fit."""
    _, laps = _plan_here(str(BARREL), "--laps", "100")
    assert "too many laps" in laps and "at most" in laps
    _, long = _plan_here(str(HOSTILE / "long_line_over_budget.yaml"))
    assert "too long" in long
    _, crawl = _plan_here(str(HOSTILE / "crawl_over_budget.yaml"))
    assert "too long" in crawl
    c = tmp_path / "step1e-4.yaml"
    c.write_text(DESIGN.read_text().replace("riccati_step_s: 0.002", "riccati_step_s: 1e-4"))
    _, step = _plan_here(str(BARREL), "--controller", str(c))
    assert "too fine a step" in step and "the finest that fits" in step
