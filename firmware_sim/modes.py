"""Flight modes in HEARTBEAT ``custom_mode``, PX4 encoding.

``custom_mode = (main_mode << 16) | (sub_mode << 24)`` (PX4's ``px4_custom_mode`` union:
main mode in bits 16-23, sub mode in bits 24-31) and ``base_mode`` carries
``MAV_MODE_FLAG_CUSTOM_MODE_ENABLED`` plus ``MAV_MODE_FLAG_SAFETY_ARMED`` when armed. The
HEARTBEAT says ``MAV_AUTOPILOT_PX4``, so pymavlink (``mode_string_v10``), MAVProxy and
MAVExplorer name the modes (LOITER, LAND, OFFBOARD). The daemon has its own copy of these
numbers (``mavreg.daemon.vehicle.messages``): the emulator stands for somebody else's firmware.
"""
from __future__ import annotations

__all__ = [
    "MAIN_AUTO", "MAIN_OFFBOARD", "SUB_AUTO_TAKEOFF", "SUB_AUTO_LOITER", "SUB_AUTO_LAND",
    "HOLD", "LAND", "OFFBOARD", "TAKEOFF", "MODE_NAMES", "custom_mode", "decode_custom_mode",
    "BASE_MODE_CUSTOM", "BASE_MODE_ARMED", "base_mode",
]

MAIN_AUTO = 4
MAIN_OFFBOARD = 6
SUB_AUTO_TAKEOFF = 2
SUB_AUTO_LOITER = 3
SUB_AUTO_LAND = 6

BASE_MODE_CUSTOM = 1    # MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
BASE_MODE_ARMED = 128   # MAV_MODE_FLAG_SAFETY_ARMED


def custom_mode(main_mode: int, sub_mode: int = 0) -> int:
    """PX4 custom_mode word for ``main_mode`` and ``sub_mode``."""
    return (main_mode << 16) | (sub_mode << 24)


def decode_custom_mode(word: int) -> tuple[int, int]:
    """Inverse of :func:`custom_mode`: ``(main_mode, sub_mode)``."""
    return (word >> 16) & 0xFF, (word >> 24) & 0xFF


def base_mode(armed: bool) -> int:
    """HEARTBEAT ``base_mode`` for the armed flag."""
    return BASE_MODE_CUSTOM | (BASE_MODE_ARMED if armed else 0)


HOLD = custom_mode(MAIN_AUTO, SUB_AUTO_LOITER)
"""AUTO.LOITER: level and hold altitude (default mode, first failsafe phase). 0x03040000."""
LAND = custom_mode(MAIN_AUTO, SUB_AUTO_LAND)
"""AUTO.LAND: descend, touch down, disarm. 0x06040000."""
OFFBOARD = custom_mode(MAIN_OFFBOARD, 0)
"""OFFBOARD: rotor thrusts (SET_ACTUATOR_CONTROL_TARGET), body rates and thrust
(SET_ATTITUDE_TARGET) or position/velocity set-points. 0x00060000."""

TAKEOFF = custom_mode(MAIN_AUTO, SUB_AUTO_TAKEOFF)
"""AUTO.TAKEOFF: climb straight up to the take-off height, then HOLD. 0x02040000."""

MODE_NAMES = {HOLD: "HOLD", LAND: "LAND", OFFBOARD: "OFFBOARD", TAKEOFF: "TAKEOFF"}
