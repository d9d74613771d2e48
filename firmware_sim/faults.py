"""Link faults in vehicle time: the lockstep-compatible shim of ``--link-faults``.

A UDP proxy between the daemon and a lockstep emulator cannot fault the link: a datagram it
delays only makes the emulator wait longer in wall-clock time (vehicle time does not move),
and a datagram it drops stalls the lockstep loop until its timeout. So the faults are
applied here, inside the emulator, in **simulation time**, after the world's own link
model (:mod:`firmware_sim.channel`): each direction of the world's delay line feeds a
:class:`mavreg.tools.faultlink.FaultLine` (the same seeded model the UDP proxy uses; the
one piece of mavreg this emulator uses besides its configuration loader: it is test
equipment, not control code).

Downlink
    What the world's line releases at a control period is one item (one datagram, as
    :meth:`firmware_sim.link.Link.send` sends it), pushed at the period's time; items are
    released at period boundaries. A corrupted item has 1..``corrupt_bits`` bits flipped
    in one of its frames, after the 10-byte header (the frame keeps its length and fails
    its CRC alone; the proxy flips anywhere). The lockstep loop waits for one command per
    state sample the daemon can use: a released ATTITUDE_QUATERNION and LOCAL_POSITION_NED
    pair, both intact, newer than every pair released before (a duplicate or an overtaken
    older sample is dropped by the daemon, which then has nothing to answer).
Uplink
    Each datagram the world's command line hands over is one item, pushed at its physics
    step and handled when due (physics-step granularity). A corrupted datagram is parsed
    again from its damaged bytes, as the vehicle would have parsed it. Valid actuator
    targets are counted for the lockstep loop on arrival, before any fault, as the world's
    own loss is (:class:`firmware_sim.engine.Engine`).

Random streams: the fault spec's ``seed`` (default: the emulator's ``--seed``), per
direction and per effect; the world's and the rotors' streams are not touched.
"""
from __future__ import annotations

import math
import random
import sys
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from mavreg.tools.faultlink.model import FaultLine, FaultParams, flip_bits, parse_faults

__all__ = ["LinkFaults", "FaultyDownlink", "FaultyUplink", "link_faults_from_args"]

_HEADER_BYTES = 10
_QUAT = "ATTITUDE_QUATERNION"
_POS = "LOCAL_POSITION_NED"


@dataclass(frozen=True)
class LinkFaults:
    """Faults of each direction (times: seconds of simulation time)."""

    up: FaultParams
    down: FaultParams


def link_faults_from_args(both: list, up: list, down: list, seed: int) -> LinkFaults | None:
    """``--link-faults`` (both ways), ``--uplink-faults``, ``--downlink-faults`` -> LinkFaults
    (``None`` when none is given). Raises ValueError with one line on a bad spec."""
    if not (both or up or down):
        return None
    notices: list = []                        # an old key in ms: one line each, not one per direction
    make = lambda specs: parse_faults(",".join(specs), seed=seed, corrupt_from=_HEADER_BYTES,  # noqa: E731
                                      on_deprecated=notices.append)
    faults = LinkFaults(make(list(both) + list(up)), make(list(both) + list(down)))
    for notice in dict.fromkeys(notices):
        print(f"firmware-sim: warning: {notice}", file=sys.stderr, flush=True)
    return faults


class _Corrupted:
    """A message packed with bits flipped after its header (``Link.send`` packs it as any
    message without a precompiled packer: ``msg.pack(mav)``)."""

    id = -1

    def __init__(self, msg, seed: int, max_bits: int):
        self.msg, self.seed, self.max_bits = msg, seed, max_bits

    def get_type(self) -> str:
        return "CORRUPTED_" + self.msg.get_type()

    def pack(self, mav, force_mavlink1: bool = False) -> bytes:
        return flip_bits(self.msg.pack(mav), random.Random(self.seed), self.max_bits, _HEADER_BYTES)


def _corrupt_down(item: list, rng: random.Random, p: FaultParams) -> list:
    k = rng.randrange(len(item))
    out = list(item)
    out[k] = _Corrupted(item[k], rng.getrandbits(32), p.corrupt_bits)
    return out


def _corrupt_up(item: list, rng: random.Random, p: FaultParams) -> list:
    k = rng.randrange(len(item))
    buf = getattr(item[k], "_msgbuf", None)
    if buf is None:
        return item
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True
    data = flip_bits(bytes(buf), rng, p.corrupt_bits, _HEADER_BYTES)
    try:
        again = parser.parse_buffer(data) or []
    except Exception as exc:             # pymavlink raises on some damaged frames
        again = [mavlink2.MAVLink_bad_data(bytearray(data), str(exc))]
    if parser.buf_len() > 0:
        again.append(mavlink2.MAVLink_bad_data(bytearray(parser.buf[parser.buf_index:]), "truncated"))
    return item[:k] + again + item[k + 1:]


class FaultyDownlink:
    """The world's :class:`~firmware_sim.channel.Downlink` followed by a fault line."""

    def __init__(self, inner, params: FaultParams, rate_hz: int):
        self.inner = inner
        self.line = FaultLine(params, "down", _corrupt_down)
        self.rate_hz = rate_hz
        self._newest_ms = -1

    # the world's interface, as the engine uses it
    def push_period(self, period: int, events: list, state: tuple) -> None:
        self.inner.push_period(period, events, state)

    def push_reply(self, step: int, msgs: list) -> None:
        self.inner.push_reply(step, msgs)

    def release(self, period: int) -> tuple[list, int]:
        """Messages due at ``period`` after both lines, and how many usable samples they hold."""
        msgs, _ = self.inner.release(period)
        t = period / self.rate_hz
        if msgs:
            self.line.push(t, list(msgs))
        out: list = []
        usable = 0
        for item in self.line.pop_due(t + 1e-9):
            out.extend(item)
            usable += self._usable(item)
        return out, usable

    def _usable(self, item: list) -> int:
        quat = {m.time_boot_ms for m in item if m.get_type() == _QUAT}
        pos = {m.time_boot_ms for m in item if m.get_type() == _POS}
        n = 0
        for t in sorted(quat & pos):
            if t > self._newest_ms:
                self._newest_ms = t
                n += 1
        return n

    @property
    def sent(self) -> int:
        return self.inner.sent

    @sent.setter
    def sent(self, value: int) -> None:
        self.inner.sent = value

    @property
    def lost(self) -> int:
        c = self.line.counters
        return self.inner.lost + c.lost + c.outage

    @property
    def pending(self) -> int:
        return self.inner.pending + self.line.in_flight


class FaultyUplink:
    """The world's :class:`~firmware_sim.channel.Uplink` followed by a fault line."""

    ideal = False

    def __init__(self, inner, params: FaultParams, physics_hz: int):
        self.inner = inner
        self.line = FaultLine(params, "up", _corrupt_up)
        self.hz = physics_hz

    def _move(self, step: int) -> None:
        for msgs in self.inner.pop_due(step):
            self.line.push(step / self.hz, msgs)

    def push(self, step: int, msgs: list, carries_target: bool) -> bool:
        ok = self.inner.push(step, msgs, carries_target)
        self._move(step)
        return ok

    def next_due(self) -> int | None:
        steps = [s for s in (self.inner.next_due(),) if s is not None]
        due = self.line.next_due()
        if due is not None:
            steps.append(int(math.ceil(due * self.hz - 1e-6)))
        return min(steps) if steps else None

    def pop_due(self, step: int) -> list:
        self._move(step)
        return self.line.pop_due((step + 1e-6) / self.hz)

    @property
    def received(self) -> int:
        return self.inner.received

    @property
    def lost(self) -> int:
        c = self.line.counters
        return self.inner.lost + c.lost + c.outage
