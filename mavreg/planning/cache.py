"""A cache of plans on disk, so that replanning an unchanged maneuver is instant.

A plan is a function of four things: the maneuver, the vehicle file, the controller file
and the code that plans. The key is the SHA-256 of all four: the loaded parameters (frozen
dataclasses, whose ``repr`` lists every field with its exact value, so a file that differs
only in comments or layout hits the same entry), the strictness, and a digest of mavreg's
own source files, so that a changed planner never serves an old plan.

Where: ``$MAVREG_PLAN_CACHE`` if set (a directory, or ``off`` to disable), else
``$XDG_CACHE_HOME/mavreg/plans``, else ``~/.cache/mavreg/plans``. An entry is a pickle of
a :class:`~mavreg.maneuver.plan_entry.PlanEntry`, the gains packed without loss (2.6-3.6 MB
for the barrel roll; the path and nominal are rebuilt bit for bit on a hit), written
atomically; the newest entries are kept, at most ``MAX_ENTRIES`` of them and at most
``MAX_BYTES`` in all (``$MAVREG_PLAN_CACHE_MAX_MB`` changes it); an entry larger than half
of that is not stored. The directory is the user's own: a pickle
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

__all__ = ["PlanCache", "default_cache", "code_digest", "MAX_ENTRIES", "MAX_BYTES", "ENV_VAR",
           "SIZE_ENV_VAR"]

ENV_VAR = "MAVREG_PLAN_CACHE"
SIZE_ENV_VAR = "MAVREG_PLAN_CACHE_MAX_MB"
MAX_ENTRIES = 16
MAX_BYTES = 256 * 2 ** 20
"""256 MiB: a dozen plans the size of the barrel roll's."""
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

    def __init__(self, directory: str | os.PathLike, max_bytes: int = MAX_BYTES):
        self.directory = FilePath(directory)
        self.max_bytes = int(max_bytes)
        self.hits = 0
        self.misses = 0
        self.last_hit = False
        """Whether the last :meth:`get_or_plan` served a stored plan."""

    @staticmethod
    def key(*inputs) -> str:
        """The entry name of a plan of ``inputs`` (their reprs) with this code."""
        h = hashlib.sha256(code_digest().encode())
        for item in inputs:
            h.update(repr(item).encode())
            h.update(b"\0")
        return h.hexdigest()

    def has(self, inputs: tuple) -> bool:
        """Whether an entry of ``inputs`` is stored (a :meth:`get_or_plan` that will, unless
        the entry is unreadable, not plan)."""
        return (self.directory / (self.key(*inputs) + _SUFFIX)).is_file()

    def get_or_plan(self, inputs: tuple, plan: Callable[[], object]):
        """The cached plan of ``inputs``, or ``plan()`` stored under their key."""
        entry = self.directory / (self.key(*inputs) + _SUFFIX)
        try:
            with open(entry, "rb") as f:
                found = pickle.load(f)
            self.hits += 1
            self.last_hit = True
            os.utime(entry)
            return found
        except Exception:     # missing, unreadable or stale: plan again
            pass
        self.misses += 1
        self.last_hit = False
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
                size = f.tell()
            if size > self.max_bytes // 2:      # would push out the rest: not kept
                os.unlink(tmp)
                return
            os.replace(tmp, entry)
            self._prune()
        except OSError:
            try:
                os.unlink(tmp)
            except OSError:
                pass

    def _prune(self) -> None:
        """Keep the newest entries within ``MAX_ENTRIES`` and ``max_bytes``."""
        entries = []
        for p in self.directory.glob("*" + _SUFFIX):
            try:
                st = p.stat()
            except OSError:
                continue
            entries.append((st.st_mtime, st.st_size, p))
        total = 0
        for i, (_, size, p) in enumerate(sorted(entries, key=lambda e: e[0], reverse=True)):
            total += size
            if i >= MAX_ENTRIES or total > self.max_bytes:
                try:
                    p.unlink()
                except OSError:
                    pass

    def size_bytes(self) -> int:
        """The bytes its entries take on disk."""
        return sum(p.stat().st_size for p in self.directory.glob("*" + _SUFFIX))


def default_cache() -> PlanCache | None:
    """The cache ``$MAVREG_PLAN_CACHE`` names (None if ``off``), else the user's."""
    setting = os.environ.get(ENV_VAR, "")
    if setting.lower() == "off":
        return None
    max_bytes = _max_bytes_setting()
    if setting:
        return PlanCache(setting, max_bytes)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return PlanCache(os.path.join(base, "mavreg", "plans"), max_bytes)


def _max_bytes_setting() -> int:
    """``$MAVREG_PLAN_CACHE_MAX_MB`` in bytes (MiB), else :data:`MAX_BYTES`."""
    text = os.environ.get(SIZE_ENV_VAR, "")
    try:
        mib = float(text)
    except ValueError:
        if text:
            raise ValueError(f"{SIZE_ENV_VAR}={text[:40]!r}: expected a size in MiB") from None
        return MAX_BYTES
    if not 0 <= mib <= 2 ** 20:
        raise ValueError(f"{SIZE_ENV_VAR}={text[:40]!r}: expected 0..1048576 MiB")
    return int(mib * 2 ** 20)
