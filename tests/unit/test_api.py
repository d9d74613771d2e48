"""``import mavreg``: a fast import that exposes the API (docs/api.md), and functions that are
the commands' own: ``mavreg.plan`` gives ``mavreg plan --json``'s figures, the defaults are the
commands'. The examples of the docstrings run in test_api_doctests.py."""
from __future__ import annotations

import json
import subprocess
import sys

import mavreg
from mavreg.cli.main import main
from mavreg.config.paths import maneuver_file
from tests.helpers.repo import ROOT

HEAVY = ("numpy", "scipy", "numba", "matplotlib", "yaml", "mavreg.api", "mavreg.cli", "mavreg.daemon")


def _child(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                          check=True, timeout=120).stdout


def test_import_mavreg_imports_nothing_heavy_until_a_name_is_used():
    out = _child("import sys, mavreg; print(sorted(m for m in sys.modules if m.startswith(%r) or "
                 "m.split('.')[0] in %r))" % ("mavreg.", HEAVY))
    assert out.strip() == "[]", out
    out = _child("import sys, mavreg; mavreg.load_vehicle; print('mavreg.api' in sys.modules, "
                 "'numpy' in sys.modules)")
    assert out.split() == ["True", "False"]            # loading files needs no numpy


def test_the_api_names_and_the_bundled_files_are_reachable():
    assert set(mavreg.__all__) <= set(dir(mavreg))
    for name in mavreg.__all__:
        assert getattr(mavreg, name).__doc__, name
    assert mavreg.config.paths.maneuver_file("barrel_roll") == maneuver_file("barrel_roll")
    assert mavreg.Plan.__module__ == "mavreg.maneuver.plan" and mavreg.simulate.__module__ == "mavreg.api"


def test_help_names_every_function_with_its_doc():
    text = _child("import mavreg; help(mavreg)")
    assert "Load, plan, simulate, look" in text
    for name in ("load_vehicle", "load_controller", "load_maneuver", "plan", "simulate", "plot_simulation"):
        assert f"\n    {name}(" in text, name
    assert "Examples" in text and ">>> import mavreg" in text


def test_the_library_plan_is_mavreg_plan(capsys):
    """Same defaults, same cache, same margins: the API's plan is the command's."""
    assert main(["plan", str(maneuver_file("barrel_roll")), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    summary = mavreg.plan(maneuver_file("barrel_roll")).summary()
    del printed["envelope"]                      # the command's check of the daemon's geofence
    printed["from_cache"] = summary["from_cache"] = None
    assert summary == printed


def test_the_old_keyword_gust_window_still_works_for_a_release_and_warns():
    """``simulate(gust_window=)`` is ``gust_window_s=`` (the CLI's ``--gust-window-s``) with a
    DeprecationWarning; the check of the window is the same under either name."""
    import pytest
    hop = mavreg.load_maneuver_text(
        "{kind: maneuver, version: 1, name: hop, start: {position_m: [0, 1, -1.5], heading_deg: 90,"
        " climb_deg: 0}, segments: [{name: line, line: {length_m: 3}}], speed: {initial_m_s: 1.0}}")
    plan = mavreg.plan(hop, margins=False)
    with pytest.raises(ValueError, match="gust_window_s must be t0 <= t1"):
        mavreg.simulate(plan, gust_window_s=(2.0, 1.0))
    with pytest.warns(DeprecationWarning, match="gust_window_s"), \
            pytest.raises(ValueError, match="gust_window_s must be t0 <= t1"):
        mavreg.simulate(plan, gust_window=(2.0, 1.0))
