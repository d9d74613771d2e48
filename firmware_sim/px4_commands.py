"""The PX4 commands and the parameter protocol of the emulator's autopilot.

Called by :class:`firmware_sim.autopilot.Autopilot` after its source and target checks (our
own system id or a configured peer's, ``target_system`` ours or 0 broadcast, ``target_component``
ours or 0). Every command gets one COMMAND_ACK:

- ``MAV_CMD_NAV_TAKEOFF`` (22): ACCEPTED when armed on the ground: the take-off mode
  (AUTO.TAKEOFF) climbs straight up to ``param7`` (AMSL, m) or, when that is NaN as MAVSDK
  sends it to PX4, to ``MIS_TAKEOFF_ALT`` above home, then holds (AUTO.LOITER). A target
  lower than ``MIS_TAKEOFF_ALT`` above home climbs to that, as PX4's navigator does. DENIED
  disarmed, in the air, or with an infinite ``param7``.
- ``MAV_CMD_NAV_LAND`` (21): ACCEPTED when armed: LAND descends at ``MPC_LAND_SPEED`` and
  disarms ``COM_DISARM_LAND`` after touchdown. DENIED disarmed.
- ``MAV_CMD_REQUEST_MESSAGE`` (512, ``param1`` the id) and the older
  ``MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES`` (520): ACCEPTED and the message follows the ack;
  FAILED for a state message before the first control period has published one; UNSUPPORTED
  for a message the emulator does not make.
- ``MAV_CMD_SET_MESSAGE_INTERVAL`` (511, ``param1`` id, ``param2`` interval in us, -1 off,
  0 default): ACCEPTED for a stream of :data:`firmware_sim.px4.DEFAULT_RATES_HZ`; UNSUPPORTED
  for another message; DENIED for an interval below -1 or a non-finite value.

COMMAND_INT is taken like COMMAND_LONG (``x``, ``y``, ``z`` as ``param5..7``).
PARAM_REQUEST_LIST answers every parameter, PARAM_REQUEST_READ one (by index, or by name with
index -1), PARAM_SET sets it when in bounds and answers the value it has afterwards (the old one
when refused, as the parameter protocol says; a read-only one, ``MPC_THR_HOVER``, is refused
and counted ``unsupported``). An unknown name or index gets no answer and is
counted ``unsupported``.
"""
from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink2

from . import modes
from .px4 import DEFAULT_RATES_HZ, PARAMS, STATE_IDS

__all__ = ["HANDLED", "CommandInt", "handle_command", "handle_param"]

M = mavlink2
HANDLED = frozenset((M.MAV_CMD_NAV_TAKEOFF, M.MAV_CMD_NAV_LAND, M.MAV_CMD_REQUEST_MESSAGE,
                     M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, M.MAV_CMD_SET_MESSAGE_INTERVAL))


class CommandInt:
    """A COMMAND_INT seen as a COMMAND_LONG (``x``, ``y`` as floats in ``param5``, ``param6``)."""

    def __init__(self, msg):
        self._msg = msg
        self.command = msg.command
        self.target_system, self.target_component = msg.target_system, msg.target_component
        self.param1, self.param2, self.param3, self.param4 = msg.param1, msg.param2, msg.param3, msg.param4
        self.param5, self.param6, self.param7 = float(msg.x), float(msg.y), msg.z

    def get_srcSystem(self):
        return self._msg.get_srcSystem()

    def get_srcComponent(self):
        return self._msg.get_srcComponent()


def handle_command(ap, msg, t_s: float, state, on_ground: bool) -> None:
    """Carry out one of :data:`HANDLED` (acked through ``ap``)."""
    c = msg.command
    if c == M.MAV_CMD_NAV_TAKEOFF:
        _takeoff(ap, msg, t_s, state, on_ground)
    elif c == M.MAV_CMD_NAV_LAND:
        if not ap.armed:
            ap.deny(msg, "land denied: disarmed")
        else:
            ap._ack(msg, M.MAV_RESULT_ACCEPTED)
            if ap.mode != modes.LAND:
                ap._set_mode(modes.LAND, t_s, "by command", state)
    elif c in (M.MAV_CMD_REQUEST_MESSAGE, M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES):
        msg_id = M.MAVLINK_MSG_ID_AUTOPILOT_VERSION if c == M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES \
            else (int(msg.param1) if math.isfinite(msg.param1) and 0 <= msg.param1 < 2 ** 24 else -1)
        reply = ap.px4.message(msg_id, ap, on_ground) if msg_id >= 0 else None
        if reply is None and msg_id in STATE_IDS:        # made, but nothing published yet
            ap._ack(msg, M.MAV_RESULT_FAILED)
        elif reply is None:
            ap.drops["unsupported"] += 1
            ap._ack(msg, M.MAV_RESULT_UNSUPPORTED)
        else:
            ap._ack(msg, M.MAV_RESULT_ACCEPTED)
            ap._out.append(reply)
    elif c == M.MAV_CMD_SET_MESSAGE_INTERVAL:
        _set_interval(ap, msg)


def _takeoff(ap, msg, t_s, state, on_ground) -> None:
    px4 = ap.px4
    if not ap.armed:
        return ap.deny(msg, "takeoff denied: disarmed")
    if not on_ground:
        return ap.deny(msg, "takeoff denied: already in the air")
    home_alt = px4.to_global(px4.home_ned)[2]
    if math.isnan(msg.param7):
        height = px4.takeoff_height_m
    elif math.isfinite(msg.param7):
        height = msg.param7 - home_alt
    else:
        return ap.deny(msg, "takeoff denied: altitude not finite")
    ap._ack(msg, M.MAV_RESULT_ACCEPTED)
    if height < px4.takeoff_height_m:        # as PX4's navigator: never below MIS_TAKEOFF_ALT
        ap._out.append(ap._statustext(M.MAV_SEVERITY_INFO, "takeoff: using minimum takeoff altitude"))
        height = px4.takeoff_height_m
    ap._set_mode(modes.TAKEOFF, t_s, f"climb to {height:.1f} m", state)
    ap.stab.reset(state)
    ap.stab.z_ref_m = px4.home_ned[2] - height
    return None


def _set_interval(ap, msg) -> None:
    if not (math.isfinite(msg.param1) and math.isfinite(msg.param2)) or msg.param2 < -1:
        ap.drops["non_finite" if not math.isfinite(msg.param1 + msg.param2) else "out_of_range"] += 1
        ap._ack(msg, M.MAV_RESULT_DENIED)
        return
    msg_id = int(msg.param1)
    if msg_id not in DEFAULT_RATES_HZ:
        ap.drops["unsupported"] += 1
        ap._ack(msg, M.MAV_RESULT_UNSUPPORTED)
        return
    ap.px4.set_interval_us(msg_id, msg.param2)
    ap._ack(msg, M.MAV_RESULT_ACCEPTED)


def handle_param(ap, msg) -> None:
    """PARAM_REQUEST_LIST, PARAM_REQUEST_READ, PARAM_SET (source and target checked by ``ap``)."""
    px4, mtype = ap.px4, msg.get_type()
    if mtype == "PARAM_REQUEST_LIST":
        ap._out.extend(px4.param_value(ap, i) for i in range(len(PARAMS)))
        return
    if mtype == "PARAM_REQUEST_READ" and msg.param_index >= 0:
        index = msg.param_index if msg.param_index < len(PARAMS) else None
    else:
        index = px4.param_index(msg.param_id)
    if index is None:
        ap.drops["unsupported"] += 1
        return
    p = PARAMS[index]
    if mtype == "PARAM_SET" and not px4.set_param(ap, index, msg.param_value):
        ap.drops["unsupported" if p.read_only else "out_of_range"] += 1
        why = "read only" if p.read_only else f"range {p.low:g}..{p.high:g}"
        ap._out.append(ap._statustext(M.MAV_SEVERITY_WARNING, f"{p.name}: refused ({why})"))
    ap._out.append(px4.param_value(ap, index))
