"""docs/examples/barrel_roll.py, the library's notebook-style example (docs/api.md), runs: it
plans, simulates and plots the barrel roll, with matplotlib's Agg backend, into a temporary
directory (a process of its own, as a user runs it; this run's plan cache)."""
from __future__ import annotations

import os
import subprocess
import sys

from tests.helpers.repo import ROOT

EXAMPLE = ROOT / "docs" / "examples" / "barrel_roll.py"


def test_the_barrel_roll_example_plans_simulates_and_plots(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p))
    proc = subprocess.run([sys.executable, str(EXAMPLE), str(tmp_path / "figures")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("barrel_roll: 40.5 m in 21.5 s, delay margin"), lines
    assert lines[1].startswith("completed: transverse error max"), lines
    for name in ("barrel_roll.png", "distance_from_path.png"):
        png = tmp_path / "figures" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name


def test_the_example_is_ten_lines_of_code():
    """The issue's promise: plan, simulate and plot in ten lines (imports and output aside)."""
    code = [ln for ln in EXAMPLE.read_text().split('"""', 2)[2].splitlines()
            if ln.strip() and not ln.lstrip().startswith(("#", "import ", "from "))]
    calls = [ln for ln in code if not ln.startswith((" ", "print(", "out = ", "out.mkdir("))]
    assert len(calls) <= 10, calls
