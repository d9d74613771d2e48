"""A non-editable install works away from the checkout: the wheel carries the parameter files.

Builds a wheel from a copy of the working tree, installs it (no dependencies: the environment
running the tests lends its numpy, numba, pymavlink ... through a ``.pth`` line, which adds a
directory to ``sys.path`` without running the editable-install hooks found there) into a fresh
virtual environment, and from a directory outside the checkout runs ``mavreg plan`` on every
maneuver of the bundled library and one lockstep ``mavreg fly --world ideal`` of a short hop.

40-60 s on two cores (the wheel and the environment 2 s, seven plans 19-27 s, the flight
18-30 s), so it is
``slow``; ``.ci/run`` runs it after the default suite.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import pytest

from mavreg.config.paths import maneuver_files
from tests.helpers.repo import ROOT as REPO

pytestmark = pytest.mark.slow

HOP = Path(__file__).resolve().parent / "signing_hop.yaml"
_ANYWHERE = shutil.ignore_patterns("__pycache__", "*.egg-info", ".pytest_cache", ".hypothesis")
_AT_ROOT = {".git", ".venv", "build", "dist", "flights", "experiments"}
"""What a clean clone lacks (``.gitignore``): build products and local outputs."""


def _ignore(directory, names):
    skip = set(_ANYWHERE(directory, names))
    return skip | (_AT_ROOT & set(names) if Path(directory) == REPO else set())


def _run(args, cwd, env, timeout=300):
    p = subprocess.run([str(a) for a in args], cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert p.returncode == 0, f"{args[:3]} exit {p.returncode}:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}"
    return p.stdout


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv python, environment, work directory outside the checkout)."""
    tmp = tmp_path_factory.mktemp("install")
    src = tmp / "src"
    shutil.copytree(REPO, src, symlinks=True, ignore=_ignore)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["MAVREG_PLAN_CACHE"] = "off"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
          "-w", tmp / "dist", src], tmp, env)
    wheel, = (tmp / "dist").glob("mavreg-*.whl")
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], tmp, env)
    py = venv / "bin" / "python"
    site = Path(_run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     tmp, env).strip())
    (site / "lender.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    _run([sys.executable, "-m", "pip", "--python", py, "install", "-q", "--no-deps", "--no-index",
          wheel], tmp, env)
    work = tmp / "work"
    work.mkdir()
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    return py, env, work


def test_the_installed_package_is_the_wheel_and_carries_the_library(installed):
    py, env, work = installed
    out = _run([py, "-c", "import mavreg, firmware_sim.params as p; from mavreg.config import paths; "
                "print(mavreg.__file__); print(p.default_vehicle_path()); "
                "print(*[f.name for f in paths.maneuver_files()])"], work, env)
    module, vehicle, names = out.splitlines()
    venv = py.parent.parent
    assert Path(module).is_relative_to(venv) and Path(vehicle).is_relative_to(venv)
    assert Path(vehicle).is_file()
    assert sorted(names.split()) == sorted(f.name for f in maneuver_files())


def test_plan_every_library_maneuver_outside_the_checkout(installed):
    py, env, work = installed
    site_params = Path(_run([py, "-c", "from mavreg.config.paths import params_dir; print(params_dir())"],
                            work, env).strip())
    maneuvers = sorted((site_params / "maneuvers").glob("*.yaml"))
    assert len(maneuvers) >= 7
    for m in maneuvers:
        text = _run(["mavreg", "plan", m], work, env)
        assert "segments" in text, text


def test_lockstep_fly_outside_the_checkout(installed):
    py, env, work = installed
    hop = work / "hop.yaml"
    hop.write_text(HOP.read_text())
    _run(["mavreg", "fly", hop, "--lockstep", "--world", "ideal", "--out", work / "out",
          "--timeout-s", "120"], work, env)
    summary = json.loads((work / "out" / "summary.json").read_text())
    assert summary["result"] == "ok" and summary["status"]["done"] == ["hop"], summary["reason"]
    assert summary["ground_truth"]["max_m"] < 0.01      # measured 0.05 mm: ideal world, ideal design
