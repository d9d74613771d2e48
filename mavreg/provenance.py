"""How a result was produced: the command, its input files and the software that ran it.

One builder (:func:`provenance`) for every result file: ``summary.json`` of ``mavreg fly``
and ``results.json`` of ``mavreg experiment`` record the same block under ``provenance``::

    {"argv": ["mavreg", "fly", ...],
     "files": {"maneuver": {"path": "...", "sha256": "..."}, "vehicle": {...}, ...},
     "world": "realistic" or null,
     "mavreg_version": "0.1.0", "git_commit": "<40 hex> or null", "git_dirty": true/false/null,
     "python_version": "3.11.2", "numpy_version": "1.26.4"}

``git_commit`` is the commit of the checkout mavreg runs from (``git rev-parse HEAD`` in the
directory holding the ``mavreg`` package, with a short timeout), null when it is not a git
checkout or git is missing; ``git_dirty`` says whether tracked files differ from that
commit (null likewise). A file that cannot be read has ``sha256: null``.
"""
from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from pathlib import Path

__all__ = ["provenance", "file_sha256", "git_state", "mavreg_version"]

GIT_TIMEOUT_S = 2.0
"""Wall seconds each git command may take (a slow network file system must not stall a run)."""

_PACKAGE_ROOT = Path(__file__).resolve().parent.parent


def file_sha256(path: str | os.PathLike) -> str | None:
    """SHA-256 (hex) of a file's bytes; None when it cannot be read."""
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return None
    return h.hexdigest()


def mavreg_version() -> str | None:
    """The installed distribution's version (None when mavreg runs uninstalled)."""
    from importlib import metadata
    try:
        return metadata.version("mavreg")
    except metadata.PackageNotFoundError:
        return None


def _git(root: Path, *args: str) -> str | None:
    try:
        r = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True,
                           timeout=GIT_TIMEOUT_S, env={**os.environ, "GIT_OPTIONAL_LOCKS": "0"})
    except (OSError, subprocess.SubprocessError):
        return None
    return r.stdout if r.returncode == 0 else None


def git_state(root: str | os.PathLike | None = None) -> tuple[str | None, bool | None]:
    """(commit, dirty) of the git checkout at ``root`` (default: the one mavreg runs from).

    (None, None) when ``root`` is not the top of a git work tree, or git is missing or slow.
    """
    root = _PACKAGE_ROOT if root is None else Path(root).resolve()
    top = _git(root, "rev-parse", "--show-toplevel")
    if top is None or Path(top.strip()).resolve() != root:
        return None, None
    commit = _git(root, "rev-parse", "HEAD")
    if commit is None:
        return None, None
    status = _git(root, "status", "--porcelain", "--untracked-files=no")
    return commit.strip(), None if status is None else bool(status.strip())


def provenance(argv, files: dict, world: str | None = None) -> dict:
    """The provenance block (module docstring) of a run.

    Parameters
    ----------
    argv : sequence of str
        The command line as typed (``["mavreg", "fly", ...]``).
    files : dict
        Role (``maneuver``, ``vehicle``, ``controller``, ``world``...) -> path, or None for a
        role that had no file (recorded as null).
    world : str, optional
        The simulated world the run flew in (the bundled emulator's preset and arguments);
        None for a vehicle of the user's.
    """
    import numpy
    commit, dirty = git_state()
    return {
        "argv": [str(a) for a in argv],
        "files": {role: None if p is None else {"path": os.fspath(p), "sha256": file_sha256(p)}
                  for role, p in files.items()},
        "world": world,
        "mavreg_version": mavreg_version(),
        "git_commit": commit,
        "git_dirty": dirty,
        "python_version": platform.python_version(),
        "numpy_version": numpy.__version__,
    }
