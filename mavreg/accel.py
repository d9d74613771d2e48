"""The optional compiled path: numba's ``njit`` where it is installed, plain Python where not.

Kernels on the hot paths (the Riccati sweep, the controller step) are written once, in the
subset of Python and numpy that numba compiles. Decorated with :func:`njit` they run compiled
when numba is importable and the environment does not set ``MAVREG_PURE=1``; otherwise the
same functions run as ordinary Python, which the tests use as the reference the compiled
path must agree with. ``ACCELERATED`` says which path is in use; ``python -m benchmarks``
prints it.

Compiled kernels are cached on disk (``cache=True``: next to the module, or in numba's user
cache when the package directory is read-only), so only the first run on a machine pays the
compile time. numba judges a cached kernel fresh by its own file's stamp alone, but a kernel
compiles in the kernels it calls from other files (the batch simulator the regulator's step,
the step the projection) and the module constants it reads (gravity): every kernel's cache is
therefore stamped with the kernels' real sources (:func:`_kernel_stamp`: the files that
declare a kernel and the package modules they import names from), and an edit of any of them
recompiles them all; an edit of a module that only calls kernels (``hover.py``) does not.
numba has no public way to add files to a cached function's stamp, so the stamp is set on
its cache object (:func:`_dispatcher`, numba's internal layout, checked: where the layout
differs, numba's own single-file stamp is used).

numba itself is imported at the first call of a kernel, not when a module declares one
(:func:`materialize`): numba and LLVM hold 65 MB or more and take a few tenths of a second
to import, which a command that calls no kernel (a plan served from the plan cache, a
rejected file, ``--help``) does not pay.
"""
from __future__ import annotations

import importlib.util
import os
import re
import sys
import threading
from functools import lru_cache, update_wrapper
from pathlib import Path

__all__ = ["ACCELERATED", "njit", "reason", "materialize", "use_compiled", "kernel_cached"]


def _find():
    """Whether numba is to be used, and why (without importing it: 65 MB and a few tenths of
    a second that a command which calls no kernel, such as planning from the plan cache or
    answering a bad file, need not pay)."""
    if os.environ.get("MAVREG_PURE", "") not in ("", "0"):
        return False, "MAVREG_PURE is set"
    if importlib.util.find_spec("numba") is None:
        return False, "numba is not installed"
    try:
        from importlib.metadata import version
        return True, f"numba {version('numba')}"
    except Exception:     # metadata missing: numba importable all the same
        return True, "numba"


ACCELERATED, reason = _find()
"""True when the kernels are compiled by numba: the one switch between the compiled kernels
and their numpy references."""


def use_compiled(compiled: bool | None, what: str) -> bool:
    """Whether an object with a compiled and a numpy path takes the compiled one: its
    ``compiled`` argument (None: :data:`ACCELERATED`). ``compiled=True`` where numba is not in
    use raises ValueError naming ``what`` (e.g. "hover step")."""
    if compiled and not ACCELERATED:
        raise ValueError(f"no compiled {what} here: numba is missing or MAVREG_PURE is set ({reason})")
    return ACCELERATED if compiled is None else bool(compiled)


_DECLARES = re.compile(r"^@njit\b|^\w+ = njit\(", re.MULTILINE)
_IMPORTS = re.compile(r"^from (\.+)([\w.]*) import", re.MULTILINE)


def _kernel_sources(root: Path) -> list[Path]:
    """The files that declare a kernel, and the package modules they import names from (a
    constant such as gravity is compiled in too)."""
    files = set()
    for f in root.rglob("*.py"):
        text = f.read_text(encoding="utf-8")
        if not _DECLARES.search(text):
            continue
        files.add(f)
        for dots, name in _IMPORTS.findall(text):
            base = f.parent
            for _ in range(len(dots) - 1):
                base = base.parent
            target = base.joinpath(*name.split(".")) if name else base
            for candidate in (target.with_suffix(".py"), target / "__init__.py"):
                if candidate.is_file() and root in candidate.parents:
                    files.add(candidate)
                    break
    files.discard(Path(__file__).resolve())
    return sorted(files)


@lru_cache(maxsize=None)
def _kernel_stamp() -> tuple:
    """(path, mtime, size) of the kernels' real sources (:func:`_kernel_sources`): the files
    whose code or constants a compiled kernel may have compiled in."""
    root = Path(__file__).resolve().parent
    return tuple((str(f.relative_to(root)), f.stat().st_mtime, f.stat().st_size) for f in _kernel_sources(root))


def _dispatcher(numba, func):
    """``numba.njit(cache=True)(func)``, its cache stamped with every kernel file."""
    dispatcher = numba.njit(cache=True)(func)
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if hasattr(cache_file, "_source_stamp"):      # numba's layout; else its own stamp alone
        cache_file._source_stamp = (cache_file._source_stamp, _kernel_stamp())
    return dispatcher


class _Kernel:
    """A kernel before numba is imported: the first call of any kernel imports numba and
    makes them all dispatchers (:func:`materialize`); calls through this object are then
    handed on."""

    def __init__(self, func):
        update_wrapper(self, func)
        self.py_func = func
        self.dispatcher = None

    @property
    def signatures(self) -> list:
        return getattr(self.dispatcher, "signatures", [])

    def __call__(self, *args):
        if self.dispatcher is None:
            materialize()
        return self.dispatcher(*args)


_pending: list[_Kernel] = []
_numba = None
_lock = threading.Lock()


def materialize() -> None:
    """Import numba, make every kernel declared so far a dispatcher, and put the dispatchers
    wherever a module holds a kernel by name (so that kernels calling kernels compile, numba
    reading their globals). Idempotent; later :func:`njit` calls return dispatchers."""
    global _numba
    with _lock:
        if _numba is not None:
            return
        try:
            import numba
        except ImportError:       # installed but broken: the kernels run as Python, correct and slow
            numba = None
        for kernel in _pending:
            kernel.dispatcher = kernel.py_func if numba is None else _dispatcher(numba, kernel.py_func)
        for module in list(sys.modules.values()):
            names = getattr(module, "__dict__", None)
            if not isinstance(names, dict):
                continue
            for name, value in list(names.items()):
                if type(value) is _Kernel:
                    names[name] = value.dispatcher
        _numba = numba if numba is not None else _Unavailable()


class _Unavailable:
    """Stands for numba when its import failed: every later kernel stays Python."""

    @staticmethod
    def njit(cache=True):
        return lambda func: func


def njit(func):
    """``numba.njit(cache=True)`` when accelerated (numba imported at the first kernel
    call), else ``func`` unchanged."""
    if not ACCELERATED:
        return func
    with _lock:
        if _numba is not None:
            return _dispatcher(_numba, func)
        kernel = _Kernel(func)
        _pending.append(kernel)
        return kernel


def kernel_cached(kernel) -> bool | None:
    """Whether numba's on-disk cache holds a fresh compiled ``kernel`` (an :func:`njit`
    function), read without compiling it: True, False (its first call compiles: a cold cache,
    or a kernel source edited since), or None where that cannot be told (numba not in use,
    or a cache layout other than the one this reads: numba's internal
    ``_cache._cache_file._load_index``, which gives nothing for a missing or stale index)."""
    if not ACCELERATED:
        return None
    materialize()
    dispatcher = getattr(kernel, "dispatcher", kernel)
    load_index = getattr(getattr(getattr(dispatcher, "_cache", None), "_cache_file", None), "_load_index", None)
    if load_index is None:
        return None
    try:
        return bool(load_index())
    except Exception:       # an unreadable index: its first call compiles
        return False
