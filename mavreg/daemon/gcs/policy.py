"""What a ground station may ask of the vehicle while mavreg flies it (pure, no I/O).

:func:`judge` decides for one message from a ground station: forward it to the vehicle,
turn it into the daemon's own landing, drop it (read-only link, a ground station's own
HEARTBEAT or TIMESYNC, a message outside the common dialect) or refuse it (it would fight
the daemon in flight). docs/ground-station.md has the table.
"""
from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink2

from ..vehicle import messages as mm

__all__ = ["FORWARD", "LAND", "DROP", "REFUSE", "NEVER_FORWARDED", "QUERY_MESSAGES", "QUERY_COMMANDS",
           "LAND_COMMANDS", "judge"]

FORWARD, LAND, DROP, REFUSE = "forward", "land", "drop", "refuse"

NEVER_FORWARDED = frozenset({"HEARTBEAT", "TIMESYNC"})
"""A ground station's HEARTBEAT would arm the vehicle's own ground-station-loss failsafe on a
link it does not own; its TIMESYNC would disturb the daemon's link-delay measurement."""

QUERY_MESSAGES = frozenset({
    "PARAM_REQUEST_READ", "PARAM_REQUEST_LIST", "REQUEST_DATA_STREAM", "MISSION_REQUEST_LIST",
    "MISSION_REQUEST_INT", "MISSION_REQUEST", "AUTOPILOT_VERSION_REQUEST", "LOG_REQUEST_LIST"})
"""Messages that only ask the vehicle for information: forwarded even during a flight."""

QUERY_COMMANDS = frozenset({
    mavlink2.MAV_CMD_REQUEST_MESSAGE, mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL,
    mavlink2.MAV_CMD_GET_MESSAGE_INTERVAL, mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES,
    mavlink2.MAV_CMD_REQUEST_PROTOCOL_VERSION, mavlink2.MAV_CMD_GET_HOME_POSITION,
    mavlink2.MAV_CMD_REQUEST_FLIGHT_INFORMATION})
"""COMMAND_LONG/COMMAND_INT commands that only ask for information or a telemetry rate."""

LAND_COMMANDS = frozenset({mavlink2.MAV_CMD_NAV_LAND, mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH})
_PX4_SUB_RTL = 5
_LAND_MODES = frozenset({(mm.PX4_MAIN_AUTO, mm.PX4_SUB_LAND), (mm.PX4_MAIN_AUTO, _PX4_SUB_RTL)})
"""PX4 (main, sub) modes that ask for a landing: AUTO.LAND and AUTO.RTL."""


def _is_land_request(msg, mtype: str) -> bool:
    if mtype in ("COMMAND_LONG", "COMMAND_INT"):
        if msg.command in LAND_COMMANDS:
            return True
        if msg.command == mavlink2.MAV_CMD_DO_SET_MODE:
            p2, p3 = msg.param2, msg.param3
            return math.isfinite(p2) and math.isfinite(p3) and (int(p2), int(p3)) in _LAND_MODES
        return False
    if mtype == "SET_MODE":
        cm = int(msg.custom_mode)
        return ((cm >> 16) & 0xFF, (cm >> 24) & 0xFF) in _LAND_MODES
    return False


def judge(msg, allow_commands: bool, in_control: bool) -> tuple[str, str]:
    """What to do with one message from a ground station: (FORWARD | LAND | DROP | REFUSE, why).

    ``in_control``: the daemon is running a flight (every phase but disarmed and aborted,
    preflight included: it may arm at any moment).
    """
    mtype = msg.get_type()
    if mtype == "BAD_DATA":
        return DROP, "not MAVLink"
    if mtype.startswith("UNKNOWN_"):
        return DROP, "a message outside the common dialect"
    if mtype in NEVER_FORWARDED:
        return DROP, f"a ground station's {mtype} is never forwarded"
    if not allow_commands:
        return DROP, "read-only (--gcs-allow-commands)"
    if _is_land_request(msg, mtype):
        return (LAND, "landing by the daemon") if in_control else (FORWARD, "")
    if not in_control:
        return FORWARD, ""
    if mtype in QUERY_MESSAGES:
        return FORWARD, ""
    if mtype in ("COMMAND_LONG", "COMMAND_INT") and msg.command in QUERY_COMMANDS:
        return FORWARD, ""
    what = f"command {msg.command}" if mtype in ("COMMAND_LONG", "COMMAND_INT") else mtype
    return REFUSE, f"{what} refused while mavreg flies"
