"""The provenance block of result files: command, input files and their hashes, software."""
from __future__ import annotations

import hashlib
import platform
import shutil
import subprocess

import numpy
import pytest

from mavreg.provenance import file_sha256, git_state, provenance
from tests.helpers.repo import ROOT as REPO


def test_files_are_hashed_and_an_unreadable_one_is_null(tmp_path):
    f = tmp_path / "m.yaml"
    f.write_bytes(b"kind: maneuver\n")
    p = provenance(["mavreg", "fly", str(f)], {"maneuver": f, "vehicle": tmp_path / "gone.yaml", "world": None},
                   world="firmware_sim --world ideal")
    assert p["argv"] == ["mavreg", "fly", str(f)]
    assert p["files"]["maneuver"] == {"path": str(f), "sha256": hashlib.sha256(b"kind: maneuver\n").hexdigest()}
    assert p["files"]["vehicle"]["sha256"] is None and p["files"]["world"] is None
    assert p["world"] == "firmware_sim --world ideal"
    assert p["python_version"] == platform.python_version() and p["numpy_version"] == numpy.__version__
    assert file_sha256(tmp_path) is None                  # a directory: not a file, no crash


@pytest.mark.skipif(shutil.which("git") is None or not (REPO / ".git").exists(), reason="not a git checkout")
def test_the_commit_of_the_checkout_mavreg_runs_from():
    head = subprocess.run(["git", "-C", str(REPO), "rev-parse", "HEAD"], capture_output=True, text=True).stdout
    commit, dirty = git_state(REPO)
    assert commit == head.strip() and isinstance(dirty, bool)
    assert provenance([], {})["git_commit"] == head.strip()       # mavreg runs from this checkout


def test_outside_a_checkout_there_is_no_commit(tmp_path):
    (tmp_path / "sub").mkdir()
    assert git_state(tmp_path / "sub") == (None, None)
    subprocess.run(["git", "init", "-q", str(tmp_path)], check=False, capture_output=True)
    assert git_state(tmp_path / "sub") == (None, None)    # inside someone else's repository: not ours
