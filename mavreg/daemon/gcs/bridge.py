"""Ground-station forwarding, sans-I/O: what goes to a ground station, what comes back.

A ground station (QGroundControl, MAVProxy) attached with ``--gcs`` watches the flight
live. :class:`GcsHub` decides, with the time injected and no sockets:

- **to the ground station**: every message the vehicle sends but its TIMESYNC answers,
  unchanged (its own system and component id, its own bytes), streamed telemetry at most
  :attr:`GcsParams.stream_rate_hz` per message type; the daemon's HEARTBEAT (component
  191, MAV_TYPE_ONBOARD_CONTROLLER) and a NAMED_VALUE_INT ``mr_phase`` of its phase code
  once a second; its STATUSTEXTs (the safety actions the vehicle also gets); at each phase
  change a STATUSTEXT and ``mr_phase``. Each endpoint has a bounded queue and a token
  bucket: a slow ground station loses messages (counted), it never delays the control loop.
- **from the ground station**: read-only by default, every message dropped and counted.
  With ``allow_commands`` (``--gcs-allow-commands``)
  :func:`mavreg.daemon.gcs.policy.judge` lets queries through
  while the daemon flies, turns a land or return request into the daemon's own landing,
  and refuses whatever would fight the daemon (mode, arming, set-points, parameters,
  missions, actuators); after the flight (disarmed or aborted) everything but the ground
  station's HEARTBEAT and TIMESYNC reaches the vehicle. Refused commands get a
  COMMAND_ACK ``MAV_RESULT_DENIED`` and, at most every :attr:`GcsParams.notice_interval_s`,
  a STATUSTEXT saying why.

:mod:`mavreg.daemon.gcs.link` is the asyncio UDP adapter.
"""
from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink2

from ..vehicle import messages as mm
from .params import GCS_DEFAULT_PORT, GcsParams, parse_gcs_url
from .policy import FORWARD, LAND, NEVER_FORWARDED, REFUSE, judge
from ..flight.phases import PHASE_CODES
from ...transport.wire import Wire

__all__ = ["GCS_DEFAULT_PORT", "GcsParams", "GcsCounters", "GcsForwarder", "GcsHub", "Received",
           "parse_gcs_url"]

OWN_COMPONENT_ID = mavlink2.MAV_COMP_ID_ONBOARD_COMPUTER

EVENT_TYPES = frozenset({
    "HEARTBEAT", "STATUSTEXT", "COMMAND_ACK", "PARAM_VALUE", "AUTOPILOT_VERSION", "PROTOCOL_VERSION",
    "MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_ITEM", "MISSION_ACK", "MISSION_REQUEST_INT",
    "NAMED_VALUE_INT"})
"""Messages that are events, not streams: never thinned by the per-type rate limit (a
parameter list or a mode change must arrive whole), only by the queue and token bucket."""

NOT_SHOWN = frozenset({"TIMESYNC"})
"""The vehicle's messages not forwarded: its TIMESYNC answers belong to the daemon's link."""

@dataclass
class GcsCounters:
    """What one endpoint forwarded and dropped (reported in the daemon's status)."""

    to_gcs: int = 0
    datagrams_out: int = 0
    dropped_rate: int = 0
    """Streamed messages thinned by the per-type rate limit."""
    dropped_queue: int = 0
    """Messages dropped because the endpoint's queue was full (a slow or absent ground station)."""
    send_errors: int = 0
    from_gcs: int = 0
    bad_data: int = 0
    foreign_address: int = 0
    dropped_read_only: int = 0
    dropped_never: int = 0
    """The ground station's HEARTBEAT and TIMESYNC (never forwarded)."""
    dropped_unknown: int = 0
    """Valid frames of messages outside the common dialect (never forwarded)."""
    refused: int = 0
    """Messages refused while the daemon flies (``--gcs-allow-commands``)."""
    to_vehicle: int = 0
    land_requests: int = 0


@dataclass
class Received:
    """The outcome of one datagram from a ground station."""

    forward: list = field(default_factory=list)
    """Messages to send to the vehicle (with the daemon's identity: the vehicle's one peer)."""
    land: bool = False
    """The ground station asked for a landing: the daemon's own land request."""


class GcsForwarder:
    """One ground-station endpoint: its queue, rate limits, parser and counters.

    Parameters
    ----------
    params : GcsParams
    """

    def __init__(self, params: GcsParams):
        self.params = params
        self.counters = GcsCounters()
        self.queue: collections.deque = collections.deque()
        self._last_by_type: dict[str, float] = {}
        self._tokens = float(params.burst_messages)
        self._tokens_t: float | None = None
        self._min_gap_s = 1.0 / params.stream_rate_hz
        self._notice_t = -math.inf
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True

    def offer(self, frame: bytes, mtype: str, now_s: float) -> bool:
        """Queue one frame for the ground station; False if the rate limit or the queue dropped it."""
        c = self.counters
        if mtype not in EVENT_TYPES:
            last = self._last_by_type.get(mtype)
            if last is not None and last <= now_s < last + self._min_gap_s - 1e-9:
                c.dropped_rate += 1
                return False
            self._last_by_type[mtype] = now_s
        if len(self.queue) >= self.params.queue_len:
            c.dropped_queue += 1
            if mtype not in EVENT_TYPES:
                return False
            self.queue.popleft()             # an event displaces the oldest waiting frame
        self.queue.append(bytes(frame))
        return True

    def drain(self, now_s: float) -> list[tuple[bytes, int]]:
        """Datagrams to send now, with their frame counts: the queue's head, as far as the
        token bucket allows."""
        p = self.params
        if self._tokens_t is not None and now_s > self._tokens_t:
            self._tokens = min(float(p.burst_messages),
                               self._tokens + (now_s - self._tokens_t) * p.max_messages_per_s)
        self._tokens_t = now_s
        out: list[tuple[bytes, int]] = []
        parts: list[bytes] = []
        size = 0
        while self.queue and self._tokens >= 1.0:
            frame = self.queue[0]
            if parts and size + len(frame) > p.max_datagram_bytes:
                out.append((b"".join(parts), len(parts)))
                parts, size = [], 0
            self.queue.popleft()
            parts.append(frame)
            size += len(frame)
            self._tokens -= 1.0
        if parts:
            out.append((b"".join(parts), len(parts)))
        return out

    def receive(self, data: bytes, in_control: bool) -> tuple[Received, list[tuple]]:
        """Parse one datagram from the ground station and judge each message.

        Returns the outcome and the refusals, (message, why) pairs, to answer."""
        c = self.counters
        res = Received()
        refused: list[tuple] = []
        try:
            msgs = self.parser.parse_buffer(data) or []
        except mavlink2.MAVError:
            c.bad_data += 1
            return res, refused
        for msg in msgs:
            if msg.get_type() == "BAD_DATA":
                c.bad_data += 1
                continue
            c.from_gcs += 1
            verdict, why = judge(msg, self.params.allow_commands, in_control)
            if verdict == FORWARD:
                res.forward.append(msg)
                c.to_vehicle += 1
            elif verdict == LAND:
                res.land = True
                c.land_requests += 1
            elif verdict == REFUSE:
                c.refused += 1
                refused.append((msg, why))
            elif msg.get_type() in NEVER_FORWARDED:
                c.dropped_never += 1
            elif msg.get_type().startswith("UNKNOWN_"):
                c.dropped_unknown += 1
            else:
                c.dropped_read_only += 1
                if msg.get_type() in ("COMMAND_LONG", "COMMAND_INT"):
                    refused.append((msg, why))
        return res, refused

    def notice_due(self, now_s: float) -> bool:
        """Whether a refusal may be explained by STATUSTEXT now (at most once per interval)."""
        if now_s - self._notice_t >= self.params.notice_interval_s or now_s < self._notice_t:
            self._notice_t = now_s
            return True
        return False


class GcsHub:
    """Every ground-station endpoint of one daemon, and the daemon's identity towards them.

    Parameters
    ----------
    n_endpoints : int
    params : GcsParams
    system_id : int
        The vehicle's system id (the daemon's too); the daemon's own messages go out as
        component 191, with sequence numbers of their own.
    """

    def __init__(self, n_endpoints: int, params: GcsParams, system_id: int):
        self.params = params
        self.endpoints = [GcsForwarder(params) for _ in range(n_endpoints)]
        self.wire = Wire(system_id, OWN_COMPONENT_ID)
        self._text_id = 0
        """STATUSTEXT chunk ids 32768-65535: the supervisor's own (repacked here with the same
        component id) count up from 1, so the two never share an id in a ground station's
        reassembly."""

    # -------------------------------------------------------------- to the GCS
    def _offer_all(self, frame: bytes, mtype: str, now_s: float) -> None:
        for ep in self.endpoints:
            ep.offer(frame, mtype, now_s)

    def _daemon(self, msg, now_s: float) -> None:
        self._offer_all(self.wire.pack(msg), msg.get_type(), now_s)

    def vehicle_message(self, msg, now_s: float) -> None:
        """One message from the vehicle, forwarded as it came (its bytes, its ids); the daemon's
        own messages follow its system id (taken from its HEARTBEAT on ``udpin:``)."""
        if msg.get_srcSystem() != self.wire.system_id:
            self.wire.identify(msg.get_srcSystem())
        mtype = msg.get_type()
        if mtype not in NOT_SHOWN:
            self._offer_all(msg.get_msgbuf(), mtype, now_s)

    def daemon_output(self, messages, events, now_s: float) -> None:
        """The daemon's STATUSTEXTs among ``messages``, and a STATUSTEXT per phase event."""
        for m in messages:
            if m.get_type() == "STATUSTEXT":
                self._daemon(m, now_s)
        for ev in events:
            if ev.kind == "phase":
                self.text(mavlink2.MAV_SEVERITY_NOTICE, f"mavreg phase {ev.phase}: {ev.detail}", now_s)
                self._phase_value(ev.phase, now_s)

    def heartbeat(self, hb, phase: str, now_s: float) -> None:
        """The daemon's HEARTBEAT and its phase code (NAMED_VALUE_INT ``mr_phase``)."""
        self._daemon(hb, now_s)
        self._phase_value(phase, now_s)

    def _phase_value(self, phase: str, now_s: float) -> None:
        self._daemon(mavlink2.MAVLink_named_value_int_message(
            int(now_s * 1e3) & 0xFFFFFFFF, b"mr_phase", PHASE_CODES.get(phase, -1)), now_s)

    def text(self, severity: int, text: str, now_s: float, endpoint: int | None = None) -> None:
        """A STATUSTEXT of the daemon's (chunked when long) to one or every endpoint."""
        self._text_id = self._text_id % 32768 + 1
        for m in mm.statustext(severity, text, 32767 + self._text_id):
            if endpoint is None:
                self._daemon(m, now_s)
            else:
                self.endpoints[endpoint].offer(self.wire.pack(m), "STATUSTEXT", now_s)

    # ------------------------------------------------------------ from the GCS
    def receive(self, i: int, data: bytes, now_s: float, in_control: bool) -> Received:
        """One datagram from endpoint ``i``; refusals are answered on that endpoint."""
        ep = self.endpoints[i]
        res, refused = ep.receive(data, in_control)
        for msg, why in refused:
            if msg.get_type() in ("COMMAND_LONG", "COMMAND_INT"):
                ack = mavlink2.MAVLink_command_ack_message(
                    msg.command, mavlink2.MAV_RESULT_DENIED, 0, 0, msg.get_srcSystem(), msg.get_srcComponent())
                ep.offer(self.wire.pack(ack), "COMMAND_ACK", now_s)
        if refused and ep.notice_due(now_s):
            self.text(mavlink2.MAV_SEVERITY_WARNING, f"mavreg gcs: {refused[0][1]}", now_s, endpoint=i)
        if res.land:
            self.text(mavlink2.MAV_SEVERITY_NOTICE, "mavreg gcs: land requested; the daemon lands",
                      now_s, endpoint=i)
        return res

    def drain(self, i: int, now_s: float) -> list[tuple[bytes, int]]:
        return self.endpoints[i].drain(now_s)

    def status(self) -> list[dict]:
        return [dict(ep.counters.__dict__, queued=len(ep.queue)) for ep in self.endpoints]
