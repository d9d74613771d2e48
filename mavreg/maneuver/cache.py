"""A cache of plans on disk, so that replanning an unchanged maneuver is instant.

A plan is a function of four things: the maneuver, the vehicle file, the controller file
and the code that plans. The key is the SHA-256 of all four: the loaded parameters (frozen
dataclasses, whose ``repr`` lists every field with its exact value, so a file that differs
only in comments or layout hits the same entry), the strictness, and a digest of mavreg's
own source files, so that a changed planner never serves an old plan.

Where: ``$MAVREG_PLAN_CACHE`` if set (a directory, or ``off`` to disable), else
``$XDG_CACHE_HOME/mavreg/plans``, else ``~/.cache/mavreg/plans``. An entry is a pickle of
the :class:`~mavreg.maneuver.plan.Plan` (about 20 MB for the barrel roll), written
atomically; the newest ``MAX_ENTRIES`` are kept. The directory is the user's own: a pickle
is code, so never point the cache at a directory others can write. An entry that cannot be
read is planned again and replaced. Failed plans (infeasible under ``strict``, bad files)
are never cached.
"""
from __future__ import annotations

import hashlib
import os
import pickle
import tempfile
from functools import lru_cache
from pathlib import Path as FilePath
from typing import Callable

__all__ = ["PlanCache", "default_cache", "code_digest", "MAX_ENTRIES", "ENV_VAR"]

ENV_VAR = "MAVREG_PLAN_CACHE"
MAX_ENTRIES = 16
_SUFFIX = ".plan.pickle"


@lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 of mavreg's Python sources (names and contents), computed once a process."""
    root = FilePath(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


class PlanCache:
    """Plans on disk under ``directory``, keyed by what they are planned from."""

    def __init__(self, directory: str | os.PathLike):
        self.directory = FilePath(directory)
        self.hits = 0
        self.misses = 0

    @staticmethod
    def key(*inputs) -> str:
        """The entry name of a plan of ``inputs`` (their reprs) with this code."""
        h = hashlib.sha256(code_digest().encode())
        for item in inputs:
            h.update(repr(item).encode())
            h.update(b"\0")
        return h.hexdigest()

    def get_or_plan(self, inputs: tuple, plan: Callable[[], object]):
        """The cached plan of ``inputs``, or ``plan()`` stored under their key."""
        entry = self.directory / (self.key(*inputs) + _SUFFIX)
        try:
            with open(entry, "rb") as f:
                found = pickle.load(f)
            self.hits += 1
            os.utime(entry)
            return found
        except Exception:     # missing, unreadable or stale: plan again
            pass
        self.misses += 1
        result = plan()
        self._store(entry, result)
        return result

    def _store(self, entry: FilePath, value) -> None:
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.directory, suffix=".tmp")
        except OSError:
            return    # a cache that cannot be written only costs time
        try:
            with os.fdopen(fd, "wb") as f:
                pickle.dump(value, f, protocol=pickle.HIGHEST_PROTOCOL)
            os.replace(tmp, entry)
            self._prune()
        except OSError:
            try:
                os.unlink(tmp)
            except OSError:
                pass

    def _prune(self) -> None:
        entries = sorted(self.directory.glob("*" + _SUFFIX), key=lambda p: p.stat().st_mtime)
        for old in entries[:-MAX_ENTRIES]:
            try:
                old.unlink()
            except OSError:
                pass


def default_cache() -> PlanCache | None:
    """The cache ``$MAVREG_PLAN_CACHE`` names (None if ``off``), else the user's."""
    setting = os.environ.get(ENV_VAR, "")
    if setting.lower() == "off":
        return None
    if setting:
        return PlanCache(setting)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return PlanCache(os.path.join(base, "mavreg", "plans"))
