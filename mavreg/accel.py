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
the step the projection): every kernel's cache is therefore stamped with all the package's
kernel files (:func:`_kernel_stamp`), and an edit of any of them recompiles them all.
"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

__all__ = ["ACCELERATED", "njit", "reason"]


def _load():
    if os.environ.get("MAVREG_PURE", "") not in ("", "0"):
        return None, "MAVREG_PURE is set"
    try:
        import numba
    except ImportError:
        return None, "numba is not installed"
    return numba, f"numba {numba.__version__}"


_numba, reason = _load()
ACCELERATED = _numba is not None
"""True when the kernels are compiled by numba."""


@lru_cache(maxsize=None)
def _kernel_stamp() -> tuple:
    """(path, mtime, size) of every module of the package that imports from this one: the
    files whose kernels a compiled kernel may have compiled in."""
    root = Path(__file__).resolve().parent
    files = sorted(f for f in root.rglob("*.py") if "accel import" in f.read_text(encoding="utf-8"))
    return tuple((str(f.relative_to(root)), f.stat().st_mtime, f.stat().st_size) for f in files)


def njit(func):
    """``numba.njit(cache=True)`` when accelerated, else ``func`` unchanged."""
    if _numba is None:
        return func
    dispatcher = _numba.njit(cache=True)(func)
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if hasattr(cache_file, "_source_stamp"):      # numba's layout; else its own stamp alone
        cache_file._source_stamp = (cache_file._source_stamp, _kernel_stamp())
    return dispatcher
