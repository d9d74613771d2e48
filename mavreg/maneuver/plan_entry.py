"""What the plan cache stores of a plan: the gain table, losslessly packed, and little else.

A :class:`~mavreg.maneuver.plan.Plan` holds about 17 MB of tables for the barrel roll (the
nominal state, its slope, input, attitude and speed on some 21 500 grid rows, the path's
Hermite table, and the gains). All but the gains come from the path and the flat nominal,
which take a few tens of milliseconds to compute again and come out the same to the last
bit (the same code on the same inputs); the gains are what the Riccati sweep costs. So an
entry keeps the gains and the few words that go with them (:class:`PlanEntry`), and
:func:`~mavreg.maneuver.plan.plan_from_entry` rebuilds the rest (for :func:`~mavreg.planning.plan_io.plan_cached`).

The gains are stored without loss: the bits of each float64 column, read as integers,
differenced three times along s (the table is smooth, so the differences are small
integers; integer arithmetic wraps, so the three cumulative sums of :func:`decode_table`
give back every bit), zig-zag folded, their bytes grouped by significance, and deflated.
About 2.6 MB for the barrel roll's (21 495, 4, 11) gains, against 7.6 MB raw.
"""
from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

__all__ = ["PlanEntry", "encode_table", "decode_table"]

_ORDER = 3
_LEVEL = 1          # deflate's fastest: within 2 % of its best on these streams, 0.05 s


def encode_table(a: np.ndarray) -> bytes:
    """``a`` (float64, any shape, first axis along s) as bytes :func:`decode_table` inverts."""
    d = np.ascontiguousarray(a, dtype=np.float64).reshape(len(a), -1).view(np.int64)
    for _ in range(_ORDER):
        d = np.concatenate([d[:1], np.diff(d, axis=0)])       # wraps: exact in int64
    z = (d << 1) ^ (d >> 63)                                   # zig-zag: small magnitudes
    planes = np.ascontiguousarray(z.T).view(np.uint8).reshape(-1, 8).T
    return zlib.compress(planes.tobytes(), _LEVEL)


def decode_table(blob: bytes, shape: tuple[int, ...]) -> np.ndarray:
    """The float64 array of ``shape`` that :func:`encode_table` packed into ``blob``."""
    n = int(shape[0])
    cols = int(np.prod(shape[1:], dtype=np.int64)) if len(shape) > 1 else 1
    planes = np.frombuffer(zlib.decompress(blob), dtype=np.uint8)
    if planes.size != 8 * n * cols:
        raise ValueError(f"a packed table of {planes.size} bytes is not {shape}")
    z = np.ascontiguousarray(planes.reshape(8, -1).T).view(np.uint64).reshape(cols, n).T
    d = (z >> np.uint64(1)).view(np.int64) ^ -(z & np.uint64(1)).view(np.int64)
    for _ in range(_ORDER):
        d = np.cumsum(d, axis=0)
    return np.ascontiguousarray(d).view(np.float64).reshape(shape)


@dataclass(frozen=True)
class PlanEntry:
    """A cached plan: its gains (packed by :func:`encode_table`) and how they ended."""

    gains: bytes
    gains_shape: tuple[int, ...]
    terminal: str
    rotor_time_constant_s: float

    @classmethod
    def of(cls, plan) -> "PlanEntry":
        return cls(encode_table(plan.K), tuple(plan.K.shape), plan.terminal,
                   float(plan.rotor_time_constant_s))

    def gain_table(self) -> np.ndarray:
        return decode_table(self.gains, self.gains_shape)
