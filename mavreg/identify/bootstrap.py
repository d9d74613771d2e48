r"""Moving-block bootstrap for least squares whose residuals are correlated in time.

The fit's rows (one per sample, three axes each) are cut into consecutive *chunks*; a
replicate draws blocks of ``block_chunks`` consecutive chunks, starting anywhere, with
replacement, until it has as many chunks as the data. What a replicate needs of the least
squares is additive over rows (:math:`X^TX`, :math:`X^Ty`, :math:`y^Ty`), so it is the
chunk sums weighted by how many times each chunk was drawn: any number of replicates costs
one matrix product, whatever the number of rows.

The block must be longer than the residuals' memory, or the bootstrap is as optimistic as
plain least squares. :func:`block_length_rows` takes it as ``factor`` times the integrated
autocorrelation time of the residuals (at least ``min_rows``).
"""
from __future__ import annotations

import numpy as np

__all__ = ["BlockBootstrap", "block_length_rows", "integrated_time_rows"]


def integrated_time_rows(resid: np.ndarray, max_lag: int | None = None) -> float:
    r"""Integrated autocorrelation time :math:`1 + 2\sum_k \rho_k` of residual rows (n, a).

    The autocorrelation is averaged over the columns and summed up to its first
    non-positive value (the initial positive sequence), which keeps noise out of the sum.
    """
    r = np.asarray(resid, float)
    r = r.reshape(r.shape[0], -1) - r.mean(axis=0).reshape(1, -1)
    n = r.shape[0]
    if n < 4:
        return 1.0
    max_lag = min(n // 4, max_lag or n // 4)
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    spec = np.fft.rfft(r, nfft, axis=0)
    acov = np.fft.irfft(spec * np.conj(spec), nfft, axis=0)[:max_lag + 1].sum(axis=1)
    rho = acov / acov[0]
    stop = np.flatnonzero(rho[1:] <= 0.0)
    k = int(stop[0]) + 1 if stop.size else rho.size
    return float(1.0 + 2.0 * rho[1:k].sum())


def block_length_rows(resid: np.ndarray, factor: float = 3.0, min_rows: int = 1) -> int:
    """``factor`` integrated autocorrelation times of the residuals, in rows."""
    return max(int(min_rows), int(np.ceil(factor * integrated_time_rows(resid))))


class BlockBootstrap:
    """Replicate weights of chunks for a moving-block bootstrap.

    Parameters
    ----------
    n_rows : int
        Rows of the data, in time order.
    chunk_rows : int
        Rows per chunk (the resolution of block starts); the last chunk may be shorter.
    block_rows : int
        Rows per block (rounded to whole chunks, at least one).
    replicates : int
    seed : int
    """

    def __init__(self, n_rows: int, chunk_rows: int, block_rows: int, replicates: int, seed: int = 0):
        chunk_rows = max(1, int(chunk_rows))
        self.starts = np.arange(0, n_rows, chunk_rows)
        n_chunks = self.starts.size
        self.block_chunks = int(min(n_chunks, max(1, round(block_rows / chunk_rows))))
        self.block_rows = self.block_chunks * chunk_rows
        per = int(np.ceil(n_chunks / self.block_chunks))
        rng = np.random.default_rng(seed)
        first = rng.integers(0, n_chunks - self.block_chunks + 1, size=(replicates, per))
        w = np.zeros((replicates, n_chunks + 1))
        rows = np.repeat(np.arange(replicates), per)
        np.add.at(w, (rows, first.ravel()), 1.0)
        np.add.at(w, (rows, first.ravel() + self.block_chunks), -1.0)
        self.weights = np.cumsum(w, axis=1)[:, :n_chunks]
        """(replicates, chunks): how many times each chunk is in the replicate."""

    @property
    def n_blocks(self) -> int:
        return int(np.ceil(self.starts.size / self.block_chunks))

    def chunk_sums(self, a: np.ndarray) -> np.ndarray:
        """Per-chunk sums of per-row arrays ``a`` (n_rows, ...) -> (chunks, ...)."""
        return np.add.reduceat(a, self.starts, axis=0)

    def replicate_sums(self, chunk_sums: np.ndarray) -> np.ndarray:
        """Weighted sums (replicates, ...) of chunk sums (chunks, ...)."""
        flat = chunk_sums.reshape(chunk_sums.shape[0], -1)
        return (self.weights @ flat).reshape((self.weights.shape[0],) + chunk_sums.shape[1:])
