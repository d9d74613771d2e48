"""BLAS and LAPACK on one thread while mavreg's numerical stages run.

mavreg's matrices are small (11 x 11 gains problems, batches of 4 x 11 products, 22 x 22
Hamiltonians): a multithreaded BLAS splits none of them usefully, and waking its threads
costs more than the arithmetic, most of all on a loaded machine (planning the barrel roll:
the Riccati stage 0.19 -> 0.13 s, the margins 0.37 -> 0.31 s at a load average of 3). The
results are the same to the last bit: the threads split the outputs of a product, not the
sums that make each one.

:func:`one_blas_thread` limits the BLAS of this process through ``threadpoolctl`` from the
call on, and leaving its ``with`` block (or calling its ``__exit__``) restores the previous
count; without threadpoolctl installed, it does nothing. The daemon holds the limit while it
runs: its per-sample path wakes BLAS threads otherwise (about 1.3 points of a core's CPU at
500 Hz, 17.6 % against 19.0 % at a load average of 2-3, the latency unchanged).
"""
from __future__ import annotations

import contextlib

__all__ = ["one_blas_thread"]


def one_blas_thread():
    """A context manager: BLAS and LAPACK on one thread inside it."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")
