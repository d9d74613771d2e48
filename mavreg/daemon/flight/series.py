"""Time-sorted sliding windows for the envelope monitor (:mod:`mavreg.daemon.flight.monitor`).

The windows are time-sorted lists searched by bisection and summed by C-level ``sum`` over a
slice: the rows a filter of the whole window would pick, at a few microseconds instead of
tens.
"""
from __future__ import annotations

from bisect import bisect_left, bisect_right

__all__ = ["Series"]


class Series:
    """Rows ``(t, a, b)`` kept sorted by time, the oldest dropped as time moves on.

    Three parallel lists and a head index (dropping is a pointer move; the lists are
    compacted now and then). Rows come in time order but for gap-filling commands, which
    stand for a vehicle time that can be later than the next sample's: those are inserted
    in place (a bisection), so the window queries can always bisect.
    """

    __slots__ = ("t", "a", "b", "head")

    def __init__(self):
        self.t: list = []
        self.a: list = []
        self.b: list = []
        self.head = 0

    def __len__(self) -> int:
        return len(self.t) - self.head

    def add(self, t: float, a, b) -> None:
        """Insert a row after every row of time ``<= t``."""
        times = self.t
        if not times or t >= times[-1]:
            times.append(t)
            self.a.append(a)
            self.b.append(b)
            return
        k = max(bisect_right(times, t, self.head), self.head)
        times.insert(k, t)
        self.a.insert(k, a)
        self.b.insert(k, b)

    def drop_older(self, t_s: float, horizon_s: float) -> None:
        """Drop rows while the oldest is more than ``horizon_s`` before ``t_s``."""
        t, h, n = self.t, self.head, len(self.t)
        while h < n and t_s - t[h] > horizon_s:
            h += 1
        self.head = h
        if h > 4096 and h > n // 2:
            del self.t[:h], self.a[:h], self.b[:h]
            self.head = 0

    def clear(self) -> None:
        self.t.clear()
        self.a.clear()
        self.b.clear()
        self.head = 0

    def newest(self):
        return self.t[-1], self.a[-1], self.b[-1]

    def within(self, t_s: float, window_s: float, strict: bool) -> int:
        """First index of the rows with ``t_s - t <= window_s`` (``<`` if strict): every row
        from there on is within, every row before is not."""
        t = self.t
        lo = self.head
        k = (bisect_right if strict else bisect_left)(t, t_s - window_s, lo)
        # bisection works on t_s - window_s; the test is on t_s - t: settle rounding at the edge
        inside = (lambda x: t_s - x < window_s) if strict else (lambda x: t_s - x <= window_s)
        while k > lo and inside(t[k - 1]):
            k -= 1
        while k < len(t) and not inside(t[k]):
            k += 1
        return k
