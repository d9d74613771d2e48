"""Which received frames the daemon takes: the vehicle's, from its address, signed when
signing is on (sans-I/O: frames and addresses in, a verdict out).

In order, each received frame is dropped, and counted by the link under the reason, if

1. it is a SETUP_SIGNING (``setup_signing``): a key never travels over the link, and such a
   frame is not even logged;
2. signing is on and :class:`mavreg.daemon.signing.Signing` refuses it (``unsigned``,
   ``bad_signature``, ``replayed``);
3. its system id and component id are not the vehicle's (``foreign_system``);
4. it comes from another address than the vehicle's (``foreign_address``). For
   ``udpout:`` the address is the URL's; for ``udpin:`` it is learned from the vehicle's
   first HEARTBEAT that passed 1-3 (authenticated, with signing on) and kept; before that
   nothing but that HEARTBEAT is taken.
"""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

__all__ = ["PeerFilter", "DROP_REASONS", "frame_ids"]

DROP_REASONS = ("setup_signing", "unsigned", "bad_signature", "replayed", "foreign_system", "foreign_address")
_HEARTBEAT = mavlink2.MAVLINK_MSG_ID_HEARTBEAT
_SETUP_SIGNING = mavlink2.MAVLINK_MSG_ID_SETUP_SIGNING


def frame_ids(frame) -> tuple[int, int, int]:
    """``(system id, component id, message id)`` from a whole MAVLink 1 or 2 frame's header."""
    if frame[0] == 0xFE:
        return frame[3], frame[4], frame[5]
    return frame[5], frame[6], frame[7] | (frame[8] << 8) | (frame[9] << 16)


class PeerFilter:
    """The daemon's receive filter for one vehicle (see the module docstring).

    Parameters
    ----------
    system_id, component_id : int
        The vehicle's ids.
    vehicle_addr : (host, port) or None
        Fixed (``udpout:``), or None to learn it (``udpin:``).
    signing : Signing or None
    """

    def __init__(self, system_id: int, component_id: int, vehicle_addr=None, signing=None):
        self.ids = (int(system_id), int(component_id))
        self.addr = None if vehicle_addr is None else tuple(vehicle_addr)
        self.signing = signing

    def admit(self, frame, addr) -> str | None:
        """``None`` to take the frame (one whole frame, received from ``addr``), else why not."""
        sysid, compid, msgid = frame_ids(frame)
        if msgid == _SETUP_SIGNING:
            return "setup_signing"
        if self.signing is not None:
            reason = self.signing.check(frame)
            if reason is not None:
                return reason
        if (sysid, compid) != self.ids:
            return "foreign_system"
        if self.addr is None:
            if msgid != _HEARTBEAT:
                return "foreign_address"
            self.addr = tuple(addr[:2])
        elif tuple(addr[:2]) != self.addr:
            return "foreign_address"
        return None
