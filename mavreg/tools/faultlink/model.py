"""A seeded, sans-I/O faulty link: items go in with a time, come out later, or never.

One :class:`FaultLine` is one direction of a link. :meth:`FaultLine.push` takes an item
(a datagram's bytes, or anything a ``corrupt`` function knows how to damage) with the time
it was sent on an injected clock; :meth:`FaultLine.pop_due` hands back, in release order,
every delivery due by a later time. No sockets, no clocks: the UDP proxy
(:mod:`mavreg.tools.faultlink.proxy`) drives it with the wall clock, firmware_sim's
lockstep shim (``firmware_sim/faults.py``) with the vehicle's simulation time.

Faults, applied in this order to each item pushed, each drawn from its **own** random
stream (``random.Random`` seeded with ``"faultlink:<seed>:<direction>:<effect>"``), so that
turning one effect on or off leaves the draws of the others unchanged:

outage
    Items pushed in ``[start, start + duration)`` of any outage are dropped (no draw).
loss
    Gilbert-Elliott: a two-state Markov chain stepped once per item; the item is lost with
    probability ``loss`` in the good state and ``burst_loss`` in the bad state; good -> bad
    with ``burst_enter``, bad -> good with ``burst_exit`` (mean burst length
    ``1 / burst_exit`` items). ``burst_enter = 0``: independent losses at rate ``loss``.
corrupt
    With probability ``corrupt``, 1 to ``corrupt_bits`` bits of the item are flipped
    (by the line's ``corrupt`` function; for bytes, uniformly over the item from byte
    ``corrupt_from``).
delay and jitter
    ``delay_s + U(0, jitter_s)``. Jitter alone never reorders: an item is released no
    earlier than the item pushed before it (FIFO, as a queue in a radio would).
reorder
    With probability ``reorder``, the item leaves the FIFO and is held ``reorder_s``
    longer: items pushed after it overtake it.
duplicate
    With probability ``duplicate``, a copy of the (possibly corrupted) item is released
    ``dup_gap_s`` after the original.

The line counts what it did (:class:`FaultCounters`).
"""
from __future__ import annotations

import heapq
import decimal
import math
import random
import warnings
from dataclasses import dataclass, fields
from typing import Any, Callable

__all__ = ["FaultParams", "FaultCounters", "FaultLine", "flip_bits", "parse_faults", "SPEC_KEYS"]


@dataclass(frozen=True)
class FaultParams:
    """Faults of one direction of a link (times in seconds of the clock that drives the line)."""

    loss: float = 0.0
    """Loss probability per item (the good state's, with bursts on)."""
    burst_enter: float = 0.0
    """Gilbert-Elliott good -> bad transition probability per item (0: no bursts)."""
    burst_exit: float = 0.5
    """Bad -> good transition probability per item (mean burst ``1 / burst_exit`` items)."""
    burst_loss: float = 1.0
    """Loss probability per item in the bad state."""
    delay_s: float = 0.0
    jitter_s: float = 0.0
    """Extra delay, uniform in [0, jitter_s]."""
    reorder: float = 0.0
    reorder_s: float = 0.01
    """How much longer a reordered item is held."""
    duplicate: float = 0.0
    dup_gap_s: float = 0.0
    """A duplicate leaves this long after its original."""
    corrupt: float = 0.0
    corrupt_bits: int = 3
    """At most this many bits flipped in a corrupted item (at least one)."""
    corrupt_from: int = 0
    """Bytes items: flips only from this byte on (the emulator keeps frame headers whole)."""
    outages: tuple = ()
    """``((start_s, duration_s), ...)``: everything pushed inside is dropped."""
    seed: int = 0

    def __post_init__(self):
        for name in ("loss", "burst_enter", "burst_exit", "burst_loss", "reorder", "duplicate", "corrupt"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 <= v <= 1.0):
                raise ValueError(f"link fault {name}={v!r}: expected a probability in [0, 1]")
        for name in ("delay_s", "jitter_s", "reorder_s", "dup_gap_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0.0 <= v <= 60.0):
                raise ValueError(f"link fault {name}={v!r}: expected seconds in [0, 60]")
        if not (1 <= int(self.corrupt_bits) <= 64) or int(self.corrupt_from) < 0:
            raise ValueError("link fault corrupt_bits must be in 1..64 and corrupt_from >= 0")
        for o in self.outages:
            if len(o) != 2 or not all(math.isfinite(x) for x in o) or o[1] < 0:
                raise ValueError(f"link fault outage {o!r}: expected (start_s, duration_s >= 0)")

    @property
    def active(self) -> bool:
        """Whether any fault is on."""
        return bool(self.loss or self.burst_enter or self.delay_s or self.jitter_s or self.reorder
                    or self.duplicate or self.corrupt or self.outages)


@dataclass
class FaultCounters:
    pushed: int = 0
    released: int = 0
    lost: int = 0
    burst_lost: int = 0
    """Lost in the Gilbert-Elliott bad state (included in ``lost``)."""
    outage: int = 0
    corrupted: int = 0
    reordered: int = 0
    duplicated: int = 0


def flip_bits(data: bytes, rng: random.Random, max_bits: int, start: int = 0) -> bytes:
    """``data`` with 1..``max_bits`` distinct bits flipped at or after byte ``start``."""
    if len(data) <= start:
        return bytes(data)
    out = bytearray(data)
    nbits = 8 * (len(out) - start)
    for pos in rng.sample(range(nbits), min(nbits, rng.randint(1, max_bits))):
        out[start + pos // 8] ^= 1 << (pos % 8)
    return bytes(out)


class ByteLoss:
    """A serial line that loses bytes: each byte lost with probability ``loss``, independently,
    from the seeded stream of ``seed`` and ``direction`` (sans-I/O: bytes in, bytes out; the
    same bytes in give the same bytes out, so a lockstep flight stays deterministic)."""

    def __init__(self, loss: float, seed: int = 0, direction: str = "down"):
        if not 0.0 <= loss < 1.0:
            raise ValueError(f"byte loss must be in [0, 1), got {loss!r}")
        self.loss = float(loss)
        self._rng = _rng(seed, direction, "byte_loss")
        self.bytes = 0
        self.lost = 0
        self._next = self._gap()

    def _gap(self) -> int:
        """Bytes passed before the next one lost (geometric)."""
        if self.loss <= 0.0:
            return 1 << 62
        return int(math.log(1.0 - self._rng.random()) / math.log1p(-self.loss))

    def apply(self, data: bytes) -> bytes:
        """What of ``data`` the line delivers."""
        self.bytes += len(data)
        if self._next >= len(data):
            self._next -= len(data)
            return data
        kept, i = [], 0
        while self._next < len(data) - i:
            j = i + self._next
            kept.append(data[i:j])
            self.lost += 1
            i = j + 1
            self._next = self._gap()
        self._next -= len(data) - i
        kept.append(data[i:])
        return b"".join(kept)


def _rng(seed: int, direction: str, effect: str) -> random.Random:
    return random.Random(f"faultlink:{seed}:{direction}:{effect}")


class FaultLine:
    """One direction of a faulty link (see the module docstring).

    Parameters
    ----------
    params : FaultParams
    direction : str
        Names the random streams (``"up"``, ``"down"``): two directions with one seed
        draw independently.
    corrupt : callable(item, rng, params) -> item, optional
        Damages an item; default: :func:`flip_bits` on bytes.
    """

    def __init__(self, params: FaultParams, direction: str = "down",
                 corrupt: Callable[[Any, random.Random, FaultParams], Any] | None = None):
        self.params = params
        s = params.seed
        self._loss = _rng(s, direction, "loss")
        self._burst = _rng(s, direction, "burst")
        self._corrupt_rng = _rng(s, direction, "corrupt")
        self._delay = _rng(s, direction, "delay")
        self._reorder = _rng(s, direction, "reorder")
        self._dup = _rng(s, direction, "duplicate")
        self._corrupt = corrupt or (lambda item, rng, p: flip_bits(item, rng, p.corrupt_bits, p.corrupt_from))
        self._bad = False
        self._fifo_last = -math.inf
        self._heap: list = []            # (release time, order, item)
        self._order = 0
        self.counters = FaultCounters()

    def _lost(self) -> bool:
        p = self.params
        if p.burst_enter:
            u = self._burst.random()
            self._bad = (u >= p.burst_exit) if self._bad else (u < p.burst_enter)
        rate = p.burst_loss if self._bad else p.loss
        if rate and self._loss.random() < rate:
            self.counters.lost += 1
            self.counters.burst_lost += self._bad
            return True
        return False

    def push(self, t_s: float, item) -> None:
        """Send ``item`` at ``t_s``."""
        p, c = self.params, self.counters
        c.pushed += 1
        if any(start <= t_s < start + dur for start, dur in p.outages):
            c.outage += 1
            return
        if (p.loss or p.burst_enter) and self._lost():
            return
        if p.corrupt and self._corrupt_rng.random() < p.corrupt:
            item = self._corrupt(item, self._corrupt_rng, p)
            c.corrupted += 1
        due = t_s + p.delay_s + (p.jitter_s * self._delay.random() if p.jitter_s else 0.0)
        if p.reorder and self._reorder.random() < p.reorder:
            due += p.reorder_s
            c.reordered += 1
        else:
            due = max(due, self._fifo_last)
            self._fifo_last = due
        self._schedule(due, item)
        if p.duplicate and self._dup.random() < p.duplicate:
            c.duplicated += 1
            self._schedule(due + p.dup_gap_s, item)

    def _schedule(self, due: float, item) -> None:
        heapq.heappush(self._heap, (due, self._order, item))
        self._order += 1

    def next_due(self) -> float | None:
        """Release time of the next delivery (``None``: nothing in flight)."""
        return self._heap[0][0] if self._heap else None

    def pop_due(self, t_s: float) -> list:
        """Every item due at or before ``t_s``, in release order (ties: push order)."""
        h, out = self._heap, []
        while h and h[0][0] <= t_s:
            out.append(heapq.heappop(h)[2])
        self.counters.released += len(out)
        return out

    @property
    def in_flight(self) -> int:
        return len(self._heap)


_SECONDS = ("delay_s", "jitter_s", "reorder_s", "dup_gap_s")
_MS_KEYS = {f"{name[:-2]}_ms": name for name in _SECONDS}
"""The keys in milliseconds of before issue 31, for one release: converted exactly, with a notice."""
SPEC_KEYS = tuple(sorted({f.name for f in fields(FaultParams)} - {"outages"} | {"outage"}))


def _ms_to_s(raw: str) -> float:
    """Milliseconds as text to seconds, exactly in decimal (``"9"`` -> 0.009, which
    ``9 * 1e-3`` is not): a key in ms and its key in s give the same double."""
    try:
        value = decimal.Decimal(raw.strip())
    except decimal.InvalidOperation:
        raise ValueError(raw) from None
    return float(value * decimal.Decimal("1e-3"))


def parse_faults(text: str, *, on_deprecated: Callable[[str], Any] | None = None, **defaults) -> FaultParams:
    """``"loss=0.1,jitter_s=0.005,outage=12.0:0.5"`` -> :class:`FaultParams`.

    Keys are the field names of :class:`FaultParams` (times in seconds, ``*_s``);
    ``outage=START_S:DURATION_S`` may be repeated. ``defaults`` are field values used
    where the text gives none (e.g. ``seed``, ``corrupt_from``). The keys in milliseconds
    of before (``delay_ms``, ``jitter_ms``, ``reorder_ms``, ``dup_gap_ms``) still work for
    one release, divided by 1000 exactly; each use calls ``on_deprecated`` with a one-line
    notice (default: a :class:`DeprecationWarning`).

    Raises
    ------
    ValueError
        One line naming the key, for an unknown key or a bad value.
    """
    values: dict = dict(defaults)
    outages = list(values.pop("outages", ()))
    names = {f.name: f for f in fields(FaultParams)}
    for part in filter(None, (p.strip() for p in text.split(","))):
        key, sep, raw = part.partition("=")
        key = key.strip()
        if not sep:
            raise ValueError(f"link faults {part[:40]!r}: expected KEY=VALUE (keys: {', '.join(SPEC_KEYS)})")
        try:
            if key == "outage":
                start, _, dur = raw.partition(":")
                outages.append((float(start), float(dur)))
            elif key in _MS_KEYS:
                values[_MS_KEYS[key]] = _ms_to_s(raw)
                _deprecated(f"link faults key {key} is deprecated and goes in the next release; use "
                            f"{_MS_KEYS[key]} (seconds)", on_deprecated)
            elif key in ("corrupt_bits", "corrupt_from", "seed"):
                values[key] = int(raw)
            elif key in names and key != "outages":
                values[key] = float(raw)
            else:
                raise KeyError(key)
        except KeyError:
            raise ValueError(f"link faults: unknown key {key[:30]!r} (keys: {', '.join(SPEC_KEYS)})") from None
        except ValueError:
            raise ValueError(f"link faults: {key[:30]}={raw[:30]!r} is not a number") from None
    return FaultParams(outages=tuple(outages), **values)


def _deprecated(notice: str, on_deprecated) -> None:
    if on_deprecated is None:
        warnings.warn(notice, DeprecationWarning, stacklevel=3)
    else:
        on_deprecated(notice)
