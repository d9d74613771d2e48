"""Whom the vehicle listens to and sends to: its configured peers (sans-I/O).

A *peer* is a system id in the configured set (``--peer-system-id``; by default only the
daemon's, which flies with the vehicle's own system id). Its component id and its address
are learned from its HEARTBEAT: the first one fixes the component, and each later one
from that system and component (re-)learns the address. With signing on, only a frame the
verifier accepted counts, so only an authenticated HEARTBEAT moves the peer.

Each decoded message of a datagram is taken, or dropped and counted under the first reason
that applies:

- ``unsigned``, ``bad_signature``, ``replayed``: signing is on and
  :class:`mavreg.transport.signing.Signing` refuses the frame;
- ``foreign_system``: its system id is not a peer's;
- ``foreign_component``: another component than the one the peer's HEARTBEAT named, or the
  vehicle's own ids (a reflected frame);
- ``foreign_address``: no HEARTBEAT of that peer yet, or another address than the one it
  was learned from.

Telemetry goes to the learned peers' addresses only, and to a ``remote`` address given at
start (``--remote``: PX4 SITL's way of sending to an offboard computer before it is heard).
``BAD_DATA`` is passed on (the autopilot counts it ``malformed``).
"""
from __future__ import annotations

__all__ = ["PeerFilter", "LINK_DROP_REASONS"]

LINK_DROP_REASONS = ("unsigned", "bad_signature", "replayed", "foreign_system", "foreign_component",
                     "foreign_address")


class PeerFilter:
    """The vehicle's receive filter (see the module docstring).

    Parameters
    ----------
    system_id, component_id : int
        The vehicle's own ids.
    peer_system_ids : iterable of int
        The systems whose commands are taken.
    signing : Signing or None
    remote : (host, port) or None
        Always sent to, from the start.
    """

    def __init__(self, system_id: int, component_id: int, peer_system_ids, signing=None, remote=None):
        self.own = (int(system_id), int(component_id))
        self.peer_system_ids = frozenset(int(s) for s in peer_system_ids)
        self.signing = signing
        self.peers: dict = {}
        """``{system id: (component id, address)}`` learned from HEARTBEATs."""
        self.remote = None if remote is None else tuple(remote)
        self.addresses: list = [] if remote is None else [self.remote]
        """Where telemetry goes: the learned peers' addresses, and ``remote``."""
        self.drops = dict.fromkeys(LINK_DROP_REASONS, 0)

    def forget(self) -> None:
        """Forget every learned peer (a reboot): telemetry goes to ``remote`` only until a
        peer's HEARTBEAT is heard again."""
        self.peers.clear()
        self.addresses[:] = [] if self.remote is None else [self.remote]

    def admit(self, msgs, addr) -> list:
        """The messages of one datagram from ``addr`` that are taken (drops counted)."""
        kept = []
        for m in msgs:
            reason = None if m.get_type() == "BAD_DATA" else self._reason(m, addr)
            if reason is None:
                kept.append(m)
            else:
                self.drops[reason] += 1
        return kept

    def _reason(self, msg, addr) -> str | None:
        if self.signing is not None:
            reason = self.signing.check(msg.get_msgbuf())
            if reason is not None:
                return reason
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        if sysid not in self.peer_system_ids:
            return "foreign_system"
        if (sysid, compid) == self.own:
            return "foreign_component"
        known = self.peers.get(sysid)
        if known is not None and compid != known[0]:
            return "foreign_component"
        if msg.get_type() == "HEARTBEAT":
            if known is None or known[1] != addr:
                self.peers[sysid] = (compid, addr)
                learned = {a for _, a in self.peers.values()}
                self.addresses[:] = sorted(learned if self.remote is None else learned | {self.remote})
            return None
        if known is None or addr != known[1]:
            return "foreign_address"
        return None
