"""Which received frames the daemon takes: the vehicle's, from its address, signed when
signing is on (sans-I/O: frames and addresses in, a verdict out).

The vehicle's system id is pinned (``--vehicle-system-id N``, and always on ``udpout:``,
where the daemon speaks first: 1 unless pinned) or, on ``udpin:``, taken from the first
**autopilot HEARTBEAT** heard (:class:`VehicleIds`): one from component 1 whose autopilot
is not ``MAV_AUTOPILOT_INVALID`` (8) and whose type is not a ground station. A ground
station's HEARTBEAT (type GCS, autopilot 8) or a companion computer's (autopilot 8) never
fixes it. The rules below then apply to every frame, the first one included.

In order, each received frame is dropped, and counted by the link under the reason, if

1. it is a SETUP_SIGNING (``setup_signing``): a key never travels over the link, and such a
   frame is not even logged;
2. signing is on and :class:`mavreg.transport.signing.Signing` refuses it (``unsigned``,
   ``bad_signature``, ``replayed``);
3. its system id and component id are not the vehicle's, or the vehicle's system id is not
   known yet and it is no autopilot HEARTBEAT (``foreign_system``); such frames are kept
   per system id (:class:`HeardSystems`) for the line that says whom the daemon heard
   instead (:meth:`PeerFilter.silence_notice`);
4. it comes from another address than the vehicle's (``foreign_address``). For
   ``udpout:`` the address is the URL's; for ``udpin:`` it is learned from the vehicle's
   first HEARTBEAT that passed 1-3 (authenticated, with signing on) and kept; before that
   nothing but that HEARTBEAT is taken. It **moves** only when the vehicle's address has
   been silent for :data:`MOVE_AFTER_S` and an autopilot HEARTBEAT of the vehicle's ids
   (passing 1-3) comes from another one: an autopilot that restarted may send from a new
   UDP port (ArduCopter's SITL does: its reboot opens its sockets again), and nothing else
   it says would ever be taken. While the vehicle talks from its address, nobody else's
   HEARTBEAT moves it; each move is one line (:meth:`PeerFilter.notice`).
"""
from __future__ import annotations

from pymavlink.dialects.v20 import common as mavlink2

from .url import learns_system_id

__all__ = ["PeerFilter", "VehicleIds", "HeardSystems", "DROP_REASONS", "frame_ids", "heartbeat_fields",
           "check_system_id", "system_id_to_use", "VEHICLE_COMPONENT_ID", "SILENCE_NOTICE_S", "MOVE_AFTER_S"]

DROP_REASONS = ("setup_signing", "unsigned", "bad_signature", "replayed", "foreign_system", "foreign_address")
VEHICLE_COMPONENT_ID = mavlink2.MAV_COMP_ID_AUTOPILOT1
"""The component whose HEARTBEAT names the vehicle (its autopilot)."""
SILENCE_NOTICE_S = 2.0
"""Seconds (injected clock) of other systems' frames, and none of the vehicle's, before the
line that says so."""
MOVE_AFTER_S = 2.0
"""Seconds (injected clock) without a frame taken from the vehicle's learned address before
its autopilot HEARTBEAT from another address moves it there: two missed 1 Hz HEARTBEATs and
hundreds of missed samples, a vehicle gone from its address (the link checks judge that
silence in the air long before)."""
_HEARTBEAT = mavlink2.MAVLINK_MSG_ID_HEARTBEAT
_SETUP_SIGNING = mavlink2.MAVLINK_MSG_ID_SETUP_SIGNING
_NOT_VEHICLES = frozenset((mavlink2.MAV_TYPE_GCS, mavlink2.MAV_TYPE_ONBOARD_CONTROLLER))


def frame_ids(frame) -> tuple[int, int, int]:
    """``(system id, component id, message id)`` from a whole MAVLink 1 or 2 frame's header."""
    if frame[0] == 0xFE:
        return frame[3], frame[4], frame[5]
    return frame[5], frame[6], frame[7] | (frame[8] << 8) | (frame[9] << 16)


def heartbeat_fields(frame) -> tuple[int, int]:
    """``(type, autopilot)`` of a whole HEARTBEAT frame, MAVLink 1 or 2 (bytes MAVLink 2
    trimmed from the payload's end are zeros)."""
    start = 6 if frame[0] == 0xFE else 10
    payload = bytes(frame[start:start + min(frame[1], 9)]) + bytes(9)
    return payload[4], payload[5]


def check_system_id(system_id) -> int:
    """``system_id`` as an int in 1..255; ValueError (one line) otherwise."""
    if isinstance(system_id, bool) or not isinstance(system_id, int) or not 1 <= system_id <= 255:
        raise ValueError(f"vehicle system id must be a whole number in 1..255, got {system_id!r}")
    return system_id


def system_id_to_use(vehicle_url: str | None, pinned: int | None) -> int | None:
    """The vehicle's system id the daemon starts with: ``pinned`` (``--vehicle-system-id``) if
    given; else None on ``udpin:``, ``serial:`` and ``tcp:`` (taken from the vehicle's first
    autopilot HEARTBEAT), and 1 on ``udpout:`` or the bundled emulator (``vehicle_url`` None),
    where the daemon speaks first and the vehicle takes only its own system id's frames."""
    if pinned is not None:
        return check_system_id(pinned)
    return None if learns_system_id(vehicle_url) else 1


class VehicleIds:
    """The vehicle's system and component id: pinned, or fixed by its first autopilot HEARTBEAT.

    Parameters
    ----------
    system_id : int or None
        1..255 to pin it; None to take it from the first HEARTBEAT of component
        ``component_id`` whose autopilot is not ``MAV_AUTOPILOT_INVALID`` and whose type is
        not a ground station or a companion computer.
    component_id : int
    """

    def __init__(self, system_id: int | None = None, component_id: int = VEHICLE_COMPONENT_ID):
        self.system_id = None if system_id is None else check_system_id(system_id)
        self.pinned = system_id is not None
        self.component_id = int(component_id)

    def take(self, system_id: int, component_id: int, heartbeat: tuple[int, int] | None) -> bool:
        """Whether a frame of these ids is the vehicle's (``heartbeat``: its ``(type,
        autopilot)`` when it is a HEARTBEAT, else None); while the system id is not known, an
        autopilot HEARTBEAT of the vehicle's component fixes it."""
        if self.system_id is None:
            if (component_id != self.component_id or heartbeat is None or heartbeat[0] in _NOT_VEHICLES
                    or heartbeat[1] == mavlink2.MAV_AUTOPILOT_INVALID):
                return False
            self.system_id = int(system_id)
        return system_id == self.system_id and component_id == self.component_id

    @property
    def target(self) -> tuple[int, int]:
        """``(system id, component id)`` to address the vehicle (known once it has been heard:
        the supervisor sends nothing before its first HEARTBEAT)."""
        if self.system_id is None:
            raise RuntimeError("the vehicle's system id is not known yet: nothing may be sent to it")
        return self.system_id, self.component_id


class HeardSystems:
    """Frames dropped as another system's, per system id (at most 256 entries: an id is a byte),
    with what its last HEARTBEAT said."""

    def __init__(self):
        self.frames: dict[int, int] = {}
        self.heartbeats: dict[int, tuple[int, int, int]] = {}
        """system id -> (component, type, autopilot) of its last HEARTBEAT."""

    def note(self, system_id: int, component_id: int, heartbeat: tuple[int, int] | None) -> None:
        self.frames[system_id] = self.frames.get(system_id, 0) + 1
        if heartbeat is not None:
            self.heartbeats[system_id] = (component_id, *heartbeat)

    def vehicles(self) -> list[int]:
        """System ids whose last HEARTBEAT is an autopilot's, from component 1 (what a pin could
        name)."""
        return sorted(s for s, (comp, vtype, ap) in self.heartbeats.items()
                      if comp == VEHICLE_COMPONENT_ID and vtype not in _NOT_VEHICLES
                      and ap != mavlink2.MAV_AUTOPILOT_INVALID)

    def describe(self, most: int = 6) -> str:
        """``system 6 (120 frames; HEARTBEAT of component 1: type 2, autopilot 12), ...``: the
        ``most`` systems heard most, in id order, and how many more (a flood of ids stays one
        short line)."""
        shown = sorted(sorted(self.frames, key=self.frames.get, reverse=True)[:most])
        parts = []
        for s in shown:
            hb = self.heartbeats.get(s)
            what = ("no HEARTBEAT" if hb is None else
                    f"HEARTBEAT of component {hb[0]}: type {hb[1]}, autopilot {hb[2]}"
                    + (", a ground station" if hb[1] == mavlink2.MAV_TYPE_GCS else "")
                    + (", not an autopilot" if hb[2] == mavlink2.MAV_AUTOPILOT_INVALID else ""))
            parts.append(f"system {s} ({self.frames[s]} frames; {what})")
        more = len(self.frames) - len(shown)
        return ", ".join(parts) + (f" and {more} more systems" if more else "")


class PeerFilter:
    """The daemon's receive filter for one vehicle (see the module docstring).

    Parameters
    ----------
    system_id : int or None
        The vehicle's system id, or None to take it from its first autopilot HEARTBEAT.
    component_id : int
        The vehicle's component id.
    vehicle_addr : (host, port) or None
        Fixed (``udpout:``), or None to learn it (``udpin:``).
    signing : Signing or None
    """

    def __init__(self, system_id: int | None, component_id: int, vehicle_addr=None, signing=None):
        self.vehicle = VehicleIds(system_id, component_id)
        self.addr = None if vehicle_addr is None else tuple(vehicle_addr)
        self.learned = vehicle_addr is None
        """The address is learned (``udpin:``), so it may move; a given one never does."""
        self.moves = 0
        """Times the vehicle's address moved."""
        self._last_taken_s: float | None = None
        self._move_line: str | None = None
        self.signing = signing
        self.heard = HeardSystems()
        self.vehicle_heard = False
        """A frame of the vehicle's has been taken."""
        self._silent_since_s: float | None = None
        self._noticed = False

    @property
    def ids(self) -> tuple[int | None, int]:
        """``(system id, component id)`` of the vehicle (system id None: not known yet)."""
        return self.vehicle.system_id, self.vehicle.component_id

    def may_move(self, now_s: float | None) -> bool:
        """Whether a frame from another address than the vehicle's could move it (``now_s``:
        the injected clock; None: never): a learned address silent for :data:`MOVE_AFTER_S`."""
        last = self._last_taken_s
        return (self.learned and self.addr is not None and now_s is not None and last is not None
                and now_s - last >= MOVE_AFTER_S)

    def admit(self, frame, addr, now_s: float | None = None) -> str | None:
        """``None`` to take the frame (one whole frame, received from ``addr`` at the injected
        clock ``now_s``; None: the address never moves), else why not."""
        sysid, compid, msgid = frame_ids(frame)
        if msgid == _SETUP_SIGNING:
            return "setup_signing"
        if self.signing is not None:
            reason = self.signing.check(frame)
            if reason is not None:
                return reason
        hb = heartbeat_fields(frame) if msgid == _HEARTBEAT else None
        if self.vehicle.system_id is None and self.addr is not None and tuple(addr[:2]) != self.addr:
            return "foreign_address"           # only the vehicle's address may name its id
        if not self.vehicle.take(sysid, compid, hb):
            self.heard.note(sysid, compid, hb)
            return "foreign_system"
        if self.addr is None:
            if hb is None:
                return "foreign_address"
            self.addr = tuple(addr[:2])
        elif tuple(addr[:2]) != self.addr:
            if (hb is None or hb[0] in _NOT_VEHICLES or hb[1] == mavlink2.MAV_AUTOPILOT_INVALID
                    or not self.may_move(now_s)):
                return "foreign_address"
            self._move_line = (f"the vehicle's HEARTBEAT now comes from {addr[0]}:{addr[1]}, its address "
                               f"{self.addr[0]}:{self.addr[1]} silent for {now_s - self._last_taken_s:.1f} s "
                               "(an autopilot that restarted): taken from there")
            self.addr = tuple(addr[:2])
            self.moves += 1
        self.vehicle_heard = True
        if now_s is not None:
            self._last_taken_s = now_s
        return None

    def notice(self, now_s: float, flag: str = "--vehicle-system-id") -> str | None:
        """A line to log, or None (call it periodically): a move of the vehicle's address
        once, else :meth:`silence_notice`."""
        line, self._move_line = self._move_line, None
        return line if line is not None else self.silence_notice(now_s, flag)

    def silence_notice(self, now_s: float, flag: str = "--vehicle-system-id") -> str | None:
        """Once, a line saying that only other systems are heard, ``SILENCE_NOTICE_S`` after
        the first call that found them so (``now_s``: the injected clock; call it
        periodically), naming them and the option ``flag`` to use; else None."""
        if self.vehicle_heard or self._noticed or not self.heard.frames:
            return None
        if self._silent_since_s is None:
            self._silent_since_s = now_s
        if now_s - self._silent_since_s < SILENCE_NOTICE_S:
            return None
        self._noticed = True
        vehicles = self.heard.vehicles()
        if len(vehicles) == 1:
            use = f"to fly it, {flag} {vehicles[0]}"
        elif vehicles:
            use = f"to fly one of them, {flag} N with N in {vehicles[:16]}" + ("..." if len(vehicles) > 16 else "")
        else:
            use = (f"none is an autopilot: check the vehicle's link, or pin its id with {flag} N "
                   "(its MAV_SYS_ID or SYSID_THISMAV)")
        if self.vehicle.pinned:
            wanted = f"nothing from the vehicle's system id {self.vehicle.system_id} ({flag})"
        else:
            wanted = (f"no autopilot HEARTBEAT (component {self.vehicle.component_id}, autopilot not "
                      "MAV_AUTOPILOT_INVALID) to take the vehicle's system id from")
        return f"{wanted} in {now_s - self._silent_since_s:.1f} s; heard only {self.heard.describe()}; {use}"
