"""Hypothesis strategies for MAVLink message fields (the property tests' half of :mod:`fuzz`;
the long run of ``python -m fuzz`` draws with :mod:`random` and needs no hypothesis)."""
from __future__ import annotations

from hypothesis import strategies as st

from .frames import EXTREME_FLOATS, layout

__all__ = ["field", "message"]


def field(ftype: str, n: int):
    """Any value of a field of MAVLink type ``ftype`` (``n`` > 0: an array of ``n``): floats
    include NaN, infinities and huge values; integers span their type."""
    if ftype == "char":
        return st.binary(max_size=max(n, 1))
    if ftype in ("float", "double"):
        one = st.one_of(st.sampled_from(EXTREME_FLOATS), st.floats(width=32 if ftype == "float" else 64))
    else:
        bits = int("".join(c for c in ftype if c.isdigit()))
        lo, hi = (0, 2 ** bits - 1) if ftype.startswith("u") else (-2 ** (bits - 1), 2 ** (bits - 1) - 1)
        one = st.integers(lo, hi)
    return st.lists(one, min_size=n, max_size=n) if n else one


def message(data, cls):
    """A message of class ``cls`` with every field drawn from :func:`field` (``data``: st.data())."""
    return cls(*[data.draw(field(t, n)) for _, t, n in layout(cls)])
