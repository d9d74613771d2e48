"""Hostile maneuver files: each gives ``mavreg plan FILE`` one line on stderr and exit 2,
quickly and in bounded memory (issue 21; docs/reliability.md, "Hostile files").

The corpus is tests/data/hostile/ (written by its generate.py); the big cases are made here
in tmp_path: a 100 MB file, /dev/zero, 100 000 waypoints, 100 000-deep nesting. Most files
run through the CLI's ``main`` in this process (fast); the worst few run as subprocesses,
whose peak memory (``os.wait4``'s rusage of that child) must stay under 300 MB. Their times
are printed, not asserted (the machine is shared).
"""
from __future__ import annotations

import contextlib
import dataclasses
import io
import os
import subprocess
import sys
import time
import typing
import warnings
from pathlib import Path

import pytest
import yaml

from mavreg.cli.common import PARAMS_DIR
from mavreg.cli.main import main
from mavreg.config.maneuver import ManeuverSpec

HOSTILE = Path(__file__).resolve().parents[1] / "data" / "hostile"
CORPUS = sorted(HOSTILE.glob("*.yaml"))
BARREL = PARAMS_DIR / "maneuvers" / "barrel_roll.yaml"
DESIGN = PARAMS_DIR / "controller" / "design.yaml"
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
        rc = main(["plan", *args])
    assert not caught, [str(w.message) for w in caught]
    return rc, err.getvalue()


def test_the_corpus_is_there():
    assert len(CORPUS) >= 80
    assert all(p.stat().st_size < 64 * 1024 for p in CORPUS)


@pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])
def test_each_corpus_file_gives_one_line_and_exit_2(path):
    _assert_one_line(*_plan_here(str(path)))


# -- every required key of the barrel roll missing in turn -------------------------------

def _required_paths(obj, schema, path=()) -> list[tuple]:
    """Key paths in ``obj`` (the YAML as loaded) whose removal the schema refuses: fields
    without a default, and a segment's shape (it needs exactly one)."""
    hints = typing.get_type_hints(schema)
    out = []
    for f in dataclasses.fields(schema):
        key = f.name[:-4] + "_deg" if f.metadata.get("deg") else f.name
        if key not in obj:
            continue
        shape = schema.__name__ == "SegmentSpec" and key in ("line", "arc", "helix", "waypoints")
        if (f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING) or shape:
            out.append(path + (key,))
        tp = hints[f.name]
        args = [a for a in typing.get_args(tp) if a is not type(None) and a is not Ellipsis]
        if dataclasses.is_dataclass(tp):
            out += _required_paths(obj[key], tp, path + (key,))
        elif args and dataclasses.is_dataclass(args[0]) and isinstance(obj[key], list):
            for i, item in enumerate(obj[key]):
                out += _required_paths(item, args[0], path + (key, i))
        elif args and dataclasses.is_dataclass(args[0]) and isinstance(obj[key], dict):
            out += _required_paths(obj[key], args[0], path + (key,))
    return out


_BARREL_DATA = yaml.safe_load(BARREL.read_text())
REQUIRED = [("kind",), ("version",)] + _required_paths(
    {k: v for k, v in _BARREL_DATA.items() if k not in ("kind", "version")}, ManeuverSpec)


def test_the_required_keys_are_found():
    """Negative control of the generator: the keys it removes include the nested ones."""
    names = {".".join(map(str, p)) for p in REQUIRED}
    assert {"name", "start.position_m", "segments.1.arc.radius_m", "segments.0.line",
            "speed.changes.1.to_m_s", "laps.segment"} <= names
    assert "limits.min_speed_m_s" not in names and "yaw.initial_deg" not in names


@pytest.mark.parametrize("key_path", REQUIRED, ids=[".".join(map(str, p)) for p in REQUIRED])
def test_each_required_key_missing_gives_one_line(key_path, tmp_path):
    import copy
    data = copy.deepcopy(_BARREL_DATA)
    parent = data
    for k in key_path[:-1]:
        parent = parent[k]
    del parent[key_path[-1]]
    f = tmp_path / "missing.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False))
    rc, err = _plan_here(str(f))
    _assert_one_line(rc, err)
    assert str(key_path[-1]) in err or "exactly one of" in err


# -- the big cases, made at test time ---------------------------------------------------

def _waypoints(n: int, compact: bool) -> str:
    """The barrel roll with its run-up replaced by ``n`` distinct waypoints."""
    if compact:
        pts = ",".join(f"[{i % 1000},{i // 1000},0]" for i in range(1, n + 1))
    else:
        pts = ",\n        ".join(f"[{(i % 100) * 0.5 + 0.5}, {i // 100 * 0.5}, 0]" for i in range(n))
    return BARREL.read_text().replace("line: {length_m: 18.0}", f"waypoints: {{points_m: [{pts}]}}")


def test_60000_waypoints_in_a_small_file(tmp_path):
    """Under the size limit (compact flow form): the node budget refuses it while composing."""
    f = tmp_path / "compact.yaml"
    f.write_text(_waypoints(60_000, compact=True))
    assert f.stat().st_size < 1 << 20
    rc, err = _plan_here(str(f))
    _assert_one_line(rc, err)
    assert "nodes" in err


def test_100000_waypoints_and_a_too_fine_step(tmp_path):
    """100 000 waypoints (2 MB): refused by size; riccati_step_s 1e-9: below the solver's step."""
    many = tmp_path / "waypoints100k.yaml"
    many.write_text(_waypoints(100_000, compact=False))
    assert many.stat().st_size > 1 << 20
    rc, err = _plan_here(str(many))
    _assert_one_line(rc, err)
    assert "larger than" in err
    fine = tmp_path / "step1e-9.yaml"
    fine.write_text(DESIGN.read_text().replace("riccati_step_s: 0.002", "riccati_step_s: 1e-9"))
    rc, err = _plan_here(str(BARREL), "--controller", str(fine))
    _assert_one_line(rc, err)
    assert "riccati_step_s" in err


def _big_cases(tmp: Path) -> dict[str, list[str]]:
    """The worst cases, as arguments of ``mavreg plan``."""
    big = tmp / "100MB.yaml"
    with open(big, "wb") as f:
        f.write(BARREL.read_bytes())
        f.truncate(100 * 2 ** 20)                 # sparse: 100 MB without writing them
    deep = tmp / "deep100k.yaml"
    deep.write_text("kind: maneuver\nversion: 1\nname: " + "[" * 100_000 + "]" * 100_000 + "\n")
    return {
        "startup (a missing file)": [str(tmp / "no_such_file.yaml")],
        "alias bomb (kind:)": [str(HOSTILE / "alias_bomb_kind.yaml")],
        "/dev/zero": ["/dev/zero"],
        "100 MB file": [str(big)],
        "100 000-deep nesting": [str(deep)],
        "--laps 100": [str(BARREL), "--laps", "100"],
    }


def _run_measured(args: list[str], tmp: Path) -> tuple[int, str, float, float]:
    """``mavreg plan ARGS`` in a subprocess: (status, stderr, seconds, peak RSS in MB)."""
    err_file = tmp / "stderr.txt"
    with open(err_file, "wb") as err, open(os.devnull, "wb") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", "mavreg.cli.main", "plan", *args],
                                stdout=out, stderr=err, env={**os.environ, "MAVREG_PLAN_CACHE": "off"})
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, err_file.read_text(errors="replace"), seconds, usage.ru_maxrss / 1024


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("hostile")
    return {name: _run_measured(args, tmp) for name, args in _big_cases(tmp).items()}


def test_the_worst_cases_give_one_line_in_a_subprocess(measured):
    for name, (rc, err, _, _) in measured.items():
        assert rc == 2 and err.count("\n") == 1, (name, rc, err[:300])
        _assert_one_line(rc, err)


def test_the_worst_cases_stay_under_300_mb(measured):
    """Peak RSS of each worst case's process; the times are reported (-s), not asserted: the
    first case, a missing file, is the cost of starting the CLI."""
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
