"""The tests keep the rules of tests/README.md ("Writing a test"), checked on the source:

- code the tests share lives in ``tests/helpers/`` (imported as ``tests.helpers.<module>``);
  every other file under ``tests/`` is a test module, a ``conftest.py`` or data; code the
  tests share with the benchmarks and the scripts (the stock-autopilot rigs) lives in
  ``harness/``, which, like ``benchmarks/`` and ``scripts/``, imports nothing from ``tests/``;
- no module imports a test module for its functions (a helper is imported instead);
- no fixed sleep stands for synchronization: a literal ``sleep(...)`` outside a loop waits
  for a time instead of a condition (:mod:`tests.helpers.waiting`). Sleeps inside a loop
  (polling, pacing) and sleeps of a named duration (a fault's timing or length) are allowed;
- a module marked ``lockstep`` (run two at a time by ``scripts/test.sh``) starts every
  emulator and every ``mavreg fly`` or ``serve`` in lockstep.

The negative controls run the same checks on generated sources.
"""
from __future__ import annotations

import ast

from tests.helpers.repo import ROOT

SHARED = ("tests/helpers/", "tests/data/")


def misplaced(relpaths: list[str]) -> list[str]:
    """The Python files under tests/ that are neither a test module, a conftest nor shared."""
    bad = []
    for rel in relpaths:
        name = rel.rsplit("/", 1)[-1]
        if rel.startswith(SHARED) or name in ("conftest.py", "__init__.py") or name.startswith("test_"):
            continue
        bad.append(rel)
    return bad


def _imports(source: str, name: str):
    """``(line, module, level)`` of every import in ``source`` (``level`` > 0: a relative one)."""
    for node in ast.walk(ast.parse(source, name)):
        if isinstance(node, ast.Import):
            yield from ((node.lineno, a.name, 0) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            yield node.lineno, node.module or "", node.level


def imports_of_test_modules(source: str, name: str) -> list[str]:
    """Imports of a test module (``test_x``, ``tests.unit.test_x``, ``tests.sitl...``) in ``source``."""
    return [f"{name}:{line}: imports {mod}" for line, mod, _ in _imports(source, name)
            if any(p.startswith("test_") for p in mod.split("."))
            or mod.startswith(("tests.unit", "tests.sitl", "tests.firmware_sim"))]


def imports_of_tests(source: str, name: str) -> list[str]:
    """Any import from the ``tests`` package in ``source`` (forbidden outside ``tests/``), or of
    a bare ``helpers`` module (which only resolves through a ``sys.path`` entry into ``tests/``)."""
    return [f"{name}:{line}: imports {mod}" for line, mod, level in _imports(source, name)
            if not level and (mod in ("tests", "helpers") or mod.startswith(("tests.", "helpers.")))]


def fixed_sleeps(source: str, name: str) -> list[str]:
    """``sleep(<literal>)`` calls outside any loop of their function, in ``source``."""
    tree = ast.parse(source, name)
    parent = {c: n for n in ast.walk(tree) for c in ast.iter_child_nodes(n)}
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Call) and isinstance(node.func, (ast.Attribute, ast.Name))
                and getattr(node.func, "attr", getattr(node.func, "id", "")) == "sleep"
                and node.args and isinstance(node.args[0], ast.Constant)):
            continue
        up, in_loop = node, False
        while up in parent and not in_loop:
            up = parent[up]
            if isinstance(up, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                break
            in_loop = isinstance(up, (ast.While, ast.For, ast.AsyncFor))
        if not in_loop:
            found.append(f"{name}:{node.lineno}: {ast.unparse(node)}")
    return found


def _sources(*folders: str):
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*.py")):
            yield path.relative_to(ROOT).as_posix(), path.read_text()


def unpaced_flights(source: str, name: str) -> list[str]:
    """In a module marked ``lockstep``: the ``start_emulator(...)`` and ``mavreg("fly" | "serve",
    ...)`` calls with no ``--lockstep`` or ``--vehicle-lockstep`` among their literal arguments."""
    if "pytest.mark.lockstep" not in source:
        return []
    bad = []
    for node in ast.walk(ast.parse(source, name)):
        if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
            continue
        consts = [a.value for a in node.args if isinstance(a, ast.Constant) and isinstance(a.value, str)]
        starts = node.func.id == "start_emulator" or (node.func.id == "mavreg" and consts[:1] in (["fly"], ["serve"]))
        if starts and not any(c in ("--lockstep", "--vehicle-lockstep") for c in consts):
            bad.append(f"{name}:{node.lineno}: {node.func.id}(...) without --lockstep")
    return bad


def test_shared_code_lives_in_tests_helpers():
    rels = [p.relative_to(ROOT).as_posix() for p in sorted((ROOT / "tests").rglob("*.py"))]
    assert misplaced(rels) == []


def test_no_module_imports_a_test_module():
    found = [f for rel, src in _sources("tests", "benchmarks", "scripts", "harness", "fuzz", "mavreg",
                                        "firmware_sim")
             for f in imports_of_test_modules(src, rel)]
    assert found == []


def test_benchmarks_scripts_and_the_harness_import_nothing_from_tests():
    found = [f for rel, src in _sources("benchmarks", "scripts", "harness", "fuzz", "mavreg", "firmware_sim")
             for f in imports_of_tests(src, rel)]
    assert found == []
    bare = [f for rel, src in _sources("tests") for f in imports_of_tests(src, rel) if " imports helpers" in f]
    assert bare == []                # tests import tests.helpers.<module>, not a bare helpers.<module>


def test_no_test_waits_a_fixed_time_for_something_to_happen():
    found = [f for rel, src in _sources("tests") for f in fixed_sleeps(src, rel)]
    assert found == []


def test_modules_run_two_at_a_time_fly_only_in_lockstep():
    found = [f for rel, src in _sources("tests") for f in unpaced_flights(src, rel)]
    marked = [rel for rel, src in _sources("tests") if "pytest.mark.lockstep" in src]
    assert found == [] and len(marked) >= 5, (found, marked)


def test_the_checks_see_what_they_forbid():
    src = ("import pytest\npytestmark = pytest.mark.lockstep\n"
           "a = start_emulator(rec, '--lockstep')\nb = mavreg('fly', 'x.yaml', '--vehicle', url)\n"
           "c = mavreg('identify', 'out')\n")
    assert [f.split(": ")[0] for f in unpaced_flights(src, "m.py")] == ["m.py:4"]
    assert unpaced_flights(src.replace("pytest.mark.lockstep", "pytest.mark.sitl"), "m.py") == []
    assert misplaced(["tests/sitl/sitl_helpers.py", "tests/unit/test_x.py", "tests/helpers/x.py",
                      "tests/sitl/conftest.py", "tests/data/hostile/generate.py"]) == ["tests/sitl/sitl_helpers.py"]
    src = "from test_state import pos\nimport tests.unit.test_plots\nfrom tests.helpers.sitl import Proc\n"
    assert [f.split(": ")[1] for f in imports_of_test_modules(src, "m.py")] == ["imports test_state",
                                                                              "imports tests.unit.test_plots"]
    src = ("import tests.helpers.repo\nfrom tests.helpers import sitl\nfrom harness import params\nfrom . import x\n"
           "from helpers.ardupilot_sitl import ArduPilotSitl\n")
    assert [f.split(": ")[1] for f in imports_of_tests(src, "m.py")] == ["imports tests.helpers.repo",
                                                                       "imports tests.helpers",
                                                                       "imports helpers.ardupilot_sitl"]
    src = ("import time, asyncio\n"
           "def f(ready, dur_s):\n"
           "    time.sleep(0.2)\n"                 # a fixed wait: found
           "    while not ready():\n"
           "        time.sleep(0.05)\n"            # polling: allowed
           "    time.sleep(dur_s)\n"               # a named duration: allowed
           "async def g():\n"
           "    await asyncio.sleep(1)\n")         # found
    assert [f.split(": ")[0] for f in fixed_sleeps(src, "m.py")] == ["m.py:3", "m.py:8"]
