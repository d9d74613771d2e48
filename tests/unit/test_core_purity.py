"""The pure core (model, geometry, control, maneuver, sim) reads no clock and no file.

An AST scan of every module of the core, for what the import contract
(``pyproject.toml``, "The pure core reads no clock and no file") cannot see: a builtin
``open``, numpy's file functions, ``Path.read_text`` and the like, a dynamic import, the
parameter-file readers of ``mavreg.config``; and the forbidden imports themselves, at any
depth (inside a function too), so that the rule holds without import-linter installed.
Files and clocks belong to the adapters: ``mavreg.planning`` (plan files, the plan cache,
``--export``), the daemon and the commands. The negative controls run the same scan on
snippets and on ``mavreg/planning``, where the I/O now lives.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

from tests.helpers.repo import ROOT

CORE = ("model", "geometry", "control", "maneuver", "sim")
FORBIDDEN_MODULES = {"time", "datetime", "os", "io", "pathlib", "tempfile", "shutil", "glob", "pickle",
                     "mmap", "socket", "asyncio", "selectors", "subprocess", "importlib", "sqlite3"}
FILE_CALLS = {"open", "input", "__import__", "exec", "eval"}
FILE_METHODS = {"load", "save", "savez", "savez_compressed", "loadtxt", "savetxt", "genfromtxt", "fromfile",
                "tofile", "memmap", "read_text", "write_text", "read_bytes", "write_bytes"}
"""Attribute calls that read or write a file (numpy's, pathlib's). ``load`` and ``save`` are
flagged on any object: the core has no other use for those names."""
CONFIG_READERS = {"load_file", "load_vehicle", "load_controller", "load_maneuver"}
"""mavreg.config's readers of parameter files (``load_maneuver_text`` parses text: allowed)."""


def impurities(source: str, name: str) -> list[str]:
    """``name:line what`` for every clock or file access the scan finds in ``source``."""
    found = []
    for node in ast.walk(ast.parse(source, name)):
        line = f"{name}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.Import):
            found += [f"{line} import {a.name}" for a in node.names
                      if a.name.split(".")[0] in FORBIDDEN_MODULES]
        elif isinstance(node, ast.ImportFrom):
            module = node.module or ""
            if node.level == 0 and module.split(".")[0] in FORBIDDEN_MODULES:
                found.append(f"{line} from {module} import ...")
            found += [f"{line} imports {a.name}" for a in node.names if a.name in CONFIG_READERS]
            if module.endswith("config.paths") or module.endswith("config.loader"):
                found.append(f"{line} from {module} import ... (the parameter files)")
        elif isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Name) and f.id in FILE_CALLS | CONFIG_READERS:
                found.append(f"{line} calls {f.id}()")
            elif isinstance(f, ast.Attribute) and f.attr in FILE_METHODS:
                found.append(f"{line} calls .{f.attr}()")
    return found


def _core_files() -> list[Path]:
    return sorted(p for pkg in CORE for p in (ROOT / "mavreg" / pkg).rglob("*.py"))


def test_the_core_reads_no_clock_and_no_file():
    files = _core_files()
    assert len(files) > 50            # the scan sees the whole core, not an empty glob
    found = [hit for f in files for hit in impurities(f.read_text(encoding="utf-8"), str(f.relative_to(ROOT)))]
    assert not found, "the pure core reads a clock or a file:\n" + "\n".join(found)


@pytest.mark.parametrize("snippet, what", [
    ("import time\n", "import time"),
    ("def f():\n    import time\n    return time.perf_counter()\n", "import time"),
    ("from pathlib import Path as FilePath\n", "from pathlib"),
    ("import os.path\n", "import os.path"),
    ("def f(p):\n    with open(p) as fh:\n        return fh.read()\n", "calls open()"),
    ("import numpy as np\ndef f(p, a):\n    np.savetxt(p, a)\n", "calls .savetxt()"),
    ("def f(p):\n    return p.read_text()\n", "calls .read_text()"),
    ("from ..config.vehicle import load_vehicle\n", "imports load_vehicle"),
    ("from ..config.paths import DEFAULT_VEHICLE\n", "the parameter files"),
    ("def f(name):\n    return __import__(name)\n", "calls __import__()"),
])
def test_the_scan_sees_a_clock_or_a_file(snippet, what):
    hits = impurities(snippet, "snippet.py")
    assert any(what in h for h in hits), hits


def test_the_scan_passes_pure_code_and_finds_the_io_where_it_now_lives():
    assert impurities("import numpy as np\nfrom ..config.maneuver import load_maneuver_text\n"
                      "def f(x):\n    return np.sin(x)\n", "pure.py") == []
    planning = sorted((ROOT / "mavreg" / "planning").glob("*.py"))
    hits = {f.name: impurities(f.read_text(encoding="utf-8"), f.name) for f in planning}
    assert hits["cache.py"] and hits["nominal_files.py"] and hits["plan_io.py"], hits


LINE = """\
kind: maneuver
version: 1
name: line
start: {position_m: [0, 0, -3], heading_deg: 0}
segments:
  - name: straight
    line: {length_m: 10.0}
speed: {initial_m_s: 3.0}
"""


def test_the_planner_times_its_stages_on_the_callers_clock_only():
    """A clock that ticks one second per read: the stages take exactly one tick each, which no
    wall clock would give; without a clock, timings are refused rather than read elsewhere."""
    from mavreg.config.controller import load_controller
    from mavreg.config.maneuver import load_maneuver_text
    from mavreg.config.paths import DEFAULT_VEHICLE, PAPER_CONTROLLER
    from mavreg.config.vehicle import load_vehicle
    from mavreg.maneuver.plan import plan_spec
    spec, vehicle, controller = (load_maneuver_text(LINE, "line.yaml"), load_vehicle(DEFAULT_VEHICLE),
                                 load_controller(PAPER_CONTROLLER))
    reads = iter(range(100))
    timings: dict = {}
    plan_spec(spec, vehicle, controller, timings=timings, clock=lambda: float(next(reads)))
    assert timings == {"path": 1.0, "nominal": 1.0, "linearization": 1.0, "riccati": 1.0, "total": 4.0}
    with pytest.raises(ValueError, match="need a clock"):
        plan_spec(spec, vehicle, controller, timings={})
    assert plan_spec(spec, vehicle, controller).K.shape[1:] == (4, 11)      # no timings: no clock needed
