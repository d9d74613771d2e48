"""scripts/venv.sh: the set-up scripts install only when .venv is missing, pyproject.toml
changed or the asked extras were never installed (so a machine once set up runs offline)."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
from tests.helpers.repo import ROOT as REPO


FAKE_PYTHON = """#!/usr/bin/env bash
echo "$*" >> "$(dirname "$0")/../../calls.log"
"""


def _ensure(root: Path, spec: str) -> list[str]:
    """Run ``ensure_venv SPEC`` in ``root``; the pip calls it made."""
    log = root / "calls.log"
    log.write_text("")
    r = subprocess.run(["bash", "-c", f"set -euo pipefail; source scripts/venv.sh; ensure_venv '{spec}'"],
                       cwd=root, capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    return [ln for ln in log.read_text().splitlines() if ln]


@pytest.fixture
def checkout(tmp_path):
    """A checkout with the real scripts and a .venv whose python only records its calls."""
    (tmp_path / "scripts").mkdir()
    shutil.copy(REPO / "scripts/venv.sh", tmp_path / "scripts/venv.sh")
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "x"\n')
    py = tmp_path / ".venv/bin/python"
    py.parent.mkdir(parents=True)
    py.write_text(FAKE_PYTHON)
    py.chmod(0o755)
    return tmp_path


def test_installs_once_then_only_when_pyproject_or_the_extras_change(checkout):
    assert _ensure(checkout, ".[test]") == ["-m pip install --quiet -e .[test]"]    # no marker yet
    assert _ensure(checkout, ".[test]") == []                                       # set up: offline
    assert _ensure(checkout, ".") == []                 # fly.sh after test.sh: the base is there
    assert _ensure(checkout, ".[test,gcs]") == ["-m pip install --quiet -e .[test,gcs]"]   # a new extra
    assert _ensure(checkout, ".[gcs]") == [] and _ensure(checkout, ".[test]") == []
    (checkout / "pyproject.toml").write_text('[project]\nname = "x"\ndependencies = ["numpy"]\n')
    assert _ensure(checkout, ".") == ["-m pip install --quiet -e ."]                # pyproject changed
    assert _ensure(checkout, ".") == []
    assert _ensure(checkout, ".[test]") == ["-m pip install --quiet -e .[test]"]    # not from this one yet
    assert _ensure(checkout, ".[test]") == [] and _ensure(checkout, ".") == []


def test_reinstall_on_request(checkout):
    _ensure(checkout, ".")
    (checkout / "calls.log").write_text("")
    r = subprocess.run(["bash", "-c", "source scripts/venv.sh; MAVREG_REINSTALL=1 ensure_venv ."],
                       cwd=checkout, capture_output=True, text=True, timeout=30)
    assert r.returncode == 0 and (checkout / "calls.log").read_text().count("pip install") == 1


def test_a_failed_install_is_tried_again(checkout):
    py = checkout / ".venv/bin/python"
    py.write_text(FAKE_PYTHON + "exit 1\n")                  # e.g. no network
    r = subprocess.run(["bash", "-c", "set -euo pipefail; source scripts/venv.sh; ensure_venv ."],
                       cwd=checkout, capture_output=True, text=True, timeout=30)
    assert r.returncode != 0
    py.write_text(FAKE_PYTHON)
    assert _ensure(checkout, ".") == ["-m pip install --quiet -e ."]


def test_the_scripts_use_it():
    for name in ("fly.sh", "test.sh"):
        text = (REPO / "scripts" / name).read_text()
        assert "source scripts/venv.sh" in text and "ensure_venv '" in text
        assert "pip install" not in text
