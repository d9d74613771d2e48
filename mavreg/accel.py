"""The optional compiled path: numba's ``njit`` where it is installed, plain Python where not.

Kernels on the hot paths (the Riccati sweep, the controller step) are written once, in the
subset of Python and numpy that numba compiles. Decorated with :func:`njit` they run compiled
when numba is importable and the environment does not set ``MAVREG_PURE=1``; otherwise the
same functions run as ordinary Python, which the tests use as the reference the compiled
path must agree with. ``ACCELERATED`` says which path is in use; ``python -m benchmarks``
prints it.

Compiled kernels are cached on disk (``cache=True``: next to the module, or in numba's user
cache when the package directory is read-only), so only the first run on a machine pays the
compile time.
"""
from __future__ import annotations

import os

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


def njit(func):
    """``numba.njit(cache=True)`` when accelerated, else ``func`` unchanged."""
    if _numba is None:
        return func
    return _numba.njit(cache=True)(func)
