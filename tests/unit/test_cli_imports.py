"""The CLI answers ``--help`` and a rejected file without importing the heavy libraries.

numba, scipy and matplotlib take most of a second and 100 MB or more to import; the command
line imports them only where a command needs them (to plan, fly, draw). Structural checks
(what a fresh interpreter has imported), not timings.
"""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from mavreg.config.paths import maneuver_file

HEAVY = ("numba", "scipy", "matplotlib")

_PROBE = """
import contextlib, io, json, sys
from mavreg.cli import main as m
m.build_parser()
code = None
argv = json.loads(sys.argv[1])
if argv:
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            code = m.main(argv)
        except SystemExit as exc:      # --help
            code = exc.code
print(json.dumps({"code": code, "heavy": sorted({k.split('.')[0] for k in sys.modules} & set(%r))}))
""" % (HEAVY,)


def _imported(argv: list[str]) -> dict:
    out = subprocess.run([sys.executable, "-c", _PROBE, json.dumps(argv)], capture_output=True,
                         text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("argv, code", [
    ([], None),                                   # import and build the parser
    (["--help"], 0),
    (["upload", "--help"], 0),
    (["plan", "/dev/null"], 2),                   # an empty file, rejected
    (["simulate", "/dev/null"], 2),
    (["plan", "no/such/file.yaml"], 2),
])
def test_light_paths_import_no_heavy_library(argv, code):
    got = _imported(argv)
    assert got["code"] == code
    assert got["heavy"] == [], f"mavreg {' '.join(argv)} imported {got['heavy']}"


def test_a_plan_from_the_cache_imports_no_numba(tmp_path, monkeypatch):
    """numba is imported at the first kernel call (:mod:`mavreg.accel`): planning imports it
    (the Riccati sweep), the same plan served from the plan cache does not. The first run is
    also the probe's negative control: it sees the heavy imports of a command that plans."""
    from mavreg import accel
    monkeypatch.setenv("MAVREG_PLAN_CACHE", str(tmp_path))
    argv = ["plan", str(maneuver_file("slalom")), "--json"]
    first, second = _imported(argv), _imported(argv)
    assert first["code"] == second["code"] == 0
    assert "scipy" in first["heavy"]
    if accel.ACCELERATED:
        assert "numba" in first["heavy"]
    assert "numba" not in second["heavy"]
