"""What differs between the autopilot families mavreg talks to (sans-I/O).

A :class:`Dialect` is chosen from the vehicle's HEARTBEAT by :func:`dialect_for` (its
``autopilot`` field: PX4 or ArduPilot; for ArduPilot only multicopter frames, whose mode
numbers are ArduCopter's), and by :func:`choose_dialect` with the operator's choice
(``--dialect`` or the vehicle file's ``dialect:``) for custom firmware that announces
``MAV_AUTOPILOT_GENERIC``: PX4's or ArduCopter's mode layout, without the parameter checks.
It decodes the armed flag and the flight mode of a heartbeat and says whether the vehicle
obeys offboard set-points (PX4 OFFBOARD, ArduCopter GUIDED); it builds the COMMAND_LONGs that
ask for that mode and for the land mode (how a flight ends on ArduCopter), and the
SET_MESSAGE_INTERVAL commands for the telemetry mavreg needs; and it lists the parameters
that must hold before arming (:class:`ParamRule`), read with PARAM_REQUEST_READ and judged
by a :class:`ParamChecker`.
Nothing here ever builds a PARAM_SET: mavreg reports a wrong safety parameter, it does not
change it. See ``docs/autopilots.md`` for the measurements behind the numbers.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, replace
from typing import NamedTuple

from .messages import PX4_MAIN_AUTO, PX4_SUB_LAND, decode_heartbeat, mavlink2, mode_name, set_offboard

__all__ = ["param_value", "ParamRule", "ParamVerdict", "ParamChecker", "HeartbeatInfo", "Dialect", "PX4",
           "ARDUCOPTER", "dialect_for", "unsupported_reason", "ARDUCOPTER_MODES", "ARDUCOPTER_GUIDED",
           "DialectChoice", "choose_dialect"]

M = mavlink2
ARDUCOPTER_GUIDED = 4
ARDUCOPTER_LAND = 9
ARDUCOPTER_MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
                    7: "CIRCLE", 9: "LAND", 11: "DRIFT", 13: "SPORT", 14: "FLIP", 15: "AUTOTUNE",
                    16: "POSHOLD", 17: "BRAKE", 18: "THROW", 19: "AVOID_ADSB", 20: "GUIDED_NOGPS",
                    21: "SMART_RTL", 22: "FLOWHOLD", 23: "FOLLOW", 24: "ZIGZAG", 25: "SYSTEMID",
                    26: "AUTOROTATE", 27: "AUTO_RTL", 28: "TURTLE"}
"""ArduCopter's flight-mode numbers (HEARTBEAT custom_mode)."""
MULTICOPTER_TYPES = frozenset((M.MAV_TYPE_QUADROTOR, M.MAV_TYPE_COAXIAL, M.MAV_TYPE_HELICOPTER,
                               M.MAV_TYPE_HEXAROTOR, M.MAV_TYPE_OCTOROTOR, M.MAV_TYPE_TRICOPTER,
                               M.MAV_TYPE_DODECAROTOR, M.MAV_TYPE_DECAROTOR))
_INT_FORMATS = {M.MAV_PARAM_TYPE_UINT8: "<B", M.MAV_PARAM_TYPE_INT8: "<b", M.MAV_PARAM_TYPE_UINT16: "<H",
                M.MAV_PARAM_TYPE_INT16: "<h", M.MAV_PARAM_TYPE_UINT32: "<I", M.MAV_PARAM_TYPE_INT32: "<i"}


def param_value(msg, bytewise: bool) -> float:
    """A PARAM_VALUE's value. ``bytewise``: an integer parameter travels with its bytes in the
    float field (PX4), else cast to float (ArduPilot)."""
    value = float(msg.param_value)
    fmt = _INT_FORMATS.get(int(msg.param_type))
    if bytewise and fmt is not None:
        value = float(struct.unpack_from(fmt, struct.pack("<f", value))[0])
    return value


@dataclass(frozen=True)
class ParamRule:
    """A parameter that must hold a condition before mavreg arms.

    ``ok(value)`` decides; ``refusal`` is the one-line reason, formatted with ``{value}``:
    it names the parameter, the value to set and why."""

    name: str
    ok: object
    refusal: str

    def check(self, value: float) -> str | None:
        """None when ``value`` is acceptable, else the refusal line."""
        if math.isfinite(value) and self.ok(value):
            return None
        return self.refusal.format(value=f"{value:g}")


@dataclass(frozen=True)
class ParamVerdict:
    """``state`` is "ok", "refused" (``lines`` say why) or "waiting" (``missing`` not yet read)."""

    state: str
    lines: tuple = ()
    missing: tuple = ()


class ParamChecker:
    """Consumes PARAM_VALUE messages and judges them against the rules.

    Parameters
    ----------
    rules : tuple of ParamRule
    bytewise : bool
        Integer parameters arrive with their bytes in the float field (PX4), not cast (ArduPilot).
    """

    def __init__(self, rules: tuple, bytewise: bool):
        self.rules = {r.name: r for r in rules}
        self.bytewise = bool(bytewise)
        self.values: dict[str, float] = {}

    def add(self, msg) -> bool:
        """Take one message; True when it was the PARAM_VALUE of a checked parameter."""
        if msg.get_type() != "PARAM_VALUE":
            return False
        name = msg.param_id.decode("ascii", "replace") if isinstance(msg.param_id, bytes) else str(msg.param_id)
        name = name.split("\x00", 1)[0]
        if name not in self.rules:
            return False
        self.values[name] = param_value(msg, self.bytewise)
        return True

    def verdict(self, timed_out: bool = False) -> ParamVerdict:
        """Refused as soon as a read value breaks its rule; ok when all are read and hold.

        Until then "waiting"; the caller bounds the wait and asks once more with
        ``timed_out=True``, which turns each missing parameter into a refusal line (an
        autopilot does not answer for a parameter it does not have)."""
        lines = tuple(line for name, v in self.values.items() if (line := self.rules[name].check(v)))
        missing = tuple(n for n in self.rules if n not in self.values)
        if timed_out:
            lines += tuple(f"{n}: no answer to PARAM_REQUEST_READ; the autopilot does not have it or "
                           "the link loses it, so mavreg cannot check it" for n in missing)
        if lines:
            return ParamVerdict("refused", lines, missing)
        return ParamVerdict("waiting", missing=missing) if missing else ParamVerdict("ok")


@dataclass(frozen=True)
class HeartbeatInfo:
    """What a vehicle HEARTBEAT says, in any dialect."""

    armed: bool
    custom_mode: int
    mode: str
    """The mode's name as the autopilot's ground stations show it."""
    offboard: bool
    """The vehicle obeys mavreg's set-points in this mode (PX4 OFFBOARD, ArduCopter GUIDED)."""
    system_status: int


@dataclass(frozen=True)
class Dialect:
    """One autopilot family: modes, commands, telemetry requests and parameter rules."""

    name: str
    autopilot: int
    offboard_mode: str
    """Name of the mode mavreg flies in."""
    rules: tuple
    max_rate_hz: float
    """Highest telemetry rate the autopilot grants by default (ArduCopter: half its 400 Hz loop;
    PX4: no cap known to mavreg, not measured)."""
    bytewise_params: bool
    disarm_by_land_mode: bool
    """After touchdown ask for the land mode (:meth:`set_land_mode`; the autopilot then disarms by
    itself) instead of ARM_DISARM 0. ArduCopter: under thrust set-points its land detector fired
    in only 2 of 10 landings, and until it fires ARM_DISARM 0 is refused; LAND disarmed 5 of 5
    (2.1 to 5.3 s after the mode change)."""

    def decode(self, hb) -> HeartbeatInfo:
        """Armed flag, mode and "obeys offboard set-points" of a vehicle HEARTBEAT."""
        armed = bool(int(hb.base_mode) & M.MAV_MODE_FLAG_SAFETY_ARMED)
        cm = int(hb.custom_mode)
        if self.autopilot == M.MAV_AUTOPILOT_PX4:
            st = decode_heartbeat(hb)
            return HeartbeatInfo(armed, cm, st.mode, st.offboard, st.system_status)
        return HeartbeatInfo(armed, cm, self.mode_name(cm), cm == ARDUCOPTER_GUIDED, int(hb.system_status))

    def mode_name(self, custom_mode: int) -> str:
        """Name of a HEARTBEAT custom_mode."""
        cm = int(custom_mode)
        if self.autopilot == M.MAV_AUTOPILOT_PX4:
            return mode_name((cm >> 16) & 0xFF, (cm >> 24) & 0xFF)
        return ARDUCOPTER_MODES.get(cm, f"MODE({cm})")

    def set_offboard_mode(self, target_system: int, target_component: int):
        """COMMAND_LONG DO_SET_MODE to the offboard mode (PX4 main mode 6; ArduCopter mode 4)."""
        if self.autopilot == M.MAV_AUTOPILOT_PX4:
            return set_offboard(target_system, target_component)
        return M.MAVLink_command_long_message(
            target_system, target_component, M.MAV_CMD_DO_SET_MODE, 0,
            float(M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(ARDUCOPTER_GUIDED), 0, 0, 0, 0, 0)

    def set_land_mode(self, target_system: int, target_component: int):
        """COMMAND_LONG DO_SET_MODE to the land mode (PX4 AUTO.LAND: main 4, sub 6; ArduCopter 9)."""
        if self.autopilot == M.MAV_AUTOPILOT_PX4:
            main, sub = PX4_MAIN_AUTO, PX4_SUB_LAND
        else:
            main, sub = ARDUCOPTER_LAND, 0
        return M.MAVLink_command_long_message(
            target_system, target_component, M.MAV_CMD_DO_SET_MODE, 0,
            float(M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), float(main), float(sub), 0, 0, 0, 0)

    @property
    def land_mode(self) -> str:
        """Name of the mode :meth:`set_land_mode` asks for, as :meth:`decode` names it."""
        return "AUTO.LAND" if self.autopilot == M.MAV_AUTOPILOT_PX4 else ARDUCOPTER_MODES[ARDUCOPTER_LAND]

    def telemetry_requests(self, target_system: int, target_component: int, rate_hz: float,
                           status_rate_hz: float = 5.0) -> list:
        """SET_MESSAGE_INTERVAL commands: ATTITUDE_QUATERNION and LOCAL_POSITION_NED at
        ``rate_hz`` (capped at :attr:`max_rate_hz`: a faster request is refused and leaves the old
        rate), EXTENDED_SYS_STATE (landed state) at ``status_rate_hz``."""
        if not (0 < rate_hz < math.inf and 0 < status_rate_hz < math.inf):
            raise ValueError(f"telemetry rates must be positive and finite, got {rate_hz}, {status_rate_hz}")
        rate = min(float(rate_hz), self.max_rate_hz)
        wanted = ((M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, rate), (M.MAVLINK_MSG_ID_LOCAL_POSITION_NED, rate),
                  (M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, min(float(status_rate_hz), rate)))
        return [M.MAVLink_command_long_message(target_system, target_component, M.MAV_CMD_SET_MESSAGE_INTERVAL,
                                               0, float(msg_id), 1e6 / hz, 0, 0, 0, 0, 0)
                for msg_id, hz in wanted]

    def param_requests(self, target_system: int, target_component: int, names=None) -> list:
        """PARAM_REQUEST_READ by name (index -1) for every checked parameter, or for ``names``
        of them (those not answered yet)."""
        wanted = [r.name for r in self.rules if names is None or r.name in names]
        return [M.MAVLink_param_request_read_message(target_system, target_component, n.encode(), -1)
                for n in wanted]

    def param_checker(self) -> ParamChecker:
        """A fresh checker for this dialect's rules (the caller bounds the wait)."""
        return ParamChecker(self.rules, self.bytewise_params)


ARDUCOPTER_RULES = (
    ParamRule("GUID_OPTIONS", lambda v: int(v) & 8 == 8,
              "GUID_OPTIONS is {value}: set bit 3 (add 8; GUID_OPTIONS=8) so the thrust mavreg sends "
              "is a thrust, not a climb rate"),
    ParamRule("GUID_TIMEOUT", lambda v: 0.0 < v <= 1.0,
              "GUID_TIMEOUT is {value} s: set 1 or less (e.g. GUID_TIMEOUT=0.5) so that when mavreg's "
              "set-points stop the vehicle levels and holds altitude within a second instead of "
              "flying on the last rates and thrust"),
    ParamRule("ATC_ANGLE_BOOST", lambda v: int(v) == 0,
              "ATC_ANGLE_BOOST is {value}: set 0 (ATC_ANGLE_BOOST=0) so the thrust mavreg sends is the "
              "thrust flown: with it on, ArduCopter divides the thrust by the cosine of the tilt and "
              "cuts it past 84 deg, upside down in a loop"),
)
PX4_RULES = (
    ParamRule("COM_OF_LOSS_T", lambda v: 0.0 < v <= 1.0,
              "COM_OF_LOSS_T is {value} s: set 1 or less (e.g. COM_OF_LOSS_T=0.5) so PX4 takes over "
              "within a second when mavreg's set-points stop"),
    ParamRule("COM_OBL_RC_ACT", lambda v: int(v) in (0, 1, 3, 4, 5),
              "COM_OBL_RC_ACT is {value}: set 5 (Hold) or 4 (Land); Stabilized (2) leaves the "
              "thrust to absent sticks, Terminate (6) and Disarm (7) stop the motors in the air"),
)
PX4 = Dialect("PX4", M.MAV_AUTOPILOT_PX4, "OFFBOARD", PX4_RULES, math.inf, True, False)
ARDUCOPTER = Dialect("ArduCopter", M.MAV_AUTOPILOT_ARDUPILOTMEGA, "GUIDED", ARDUCOPTER_RULES, 200.0, False,
                     True)


def dialect_for(hb) -> Dialect | None:
    """The dialect of a vehicle HEARTBEAT, or None (another autopilot, or ArduPilot not a copter;
    :func:`unsupported_reason` says which)."""
    autopilot, vtype = int(hb.autopilot), int(hb.type)
    if autopilot == M.MAV_AUTOPILOT_PX4:
        return PX4
    if autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA and vtype in MULTICOPTER_TYPES:
        return ARDUCOPTER
    return None


def unsupported_reason(hb) -> str:
    """One line saying why :func:`dialect_for` found no dialect for this HEARTBEAT."""
    autopilot, vtype = int(hb.autopilot), int(hb.type)
    if autopilot == M.MAV_AUTOPILOT_ARDUPILOTMEGA:
        return f"ArduPilot vehicle of MAV_TYPE {vtype} is not a multicopter: only ArduCopter is supported"
    return (f"autopilot {autopilot} (MAV_AUTOPILOT) is neither PX4 (12) nor ArduPilot (3) nor custom firmware "
            "that announces GENERIC (0)")


class DialectChoice(NamedTuple):
    """What :func:`choose_dialect` decided: a dialect, or a refusal, and a notice to show."""

    dialect: Dialect | None
    refusal: str | None = None
    """Why mavreg does not fly this vehicle (one line); None when ``dialect`` is set."""
    notice: str | None = None
    """One line for the operator: the mode layout a GENERIC vehicle is flown with."""


_LAYOUTS = {"px4": PX4, "ardupilot": ARDUCOPTER}
_CHOOSE = "--dialect px4|ardupilot (or dialect: in the vehicle file)"


def choose_dialect(hb, choice: str | None = None, output: str = "rotors") -> DialectChoice:
    """The dialect of a vehicle HEARTBEAT with the operator's ``choice`` (``px4``, ``ardupilot``
    or None) for the ``output`` flown (``rotors`` or ``rates``).

    PX4 and ArduCopter are known from the HEARTBEAT; a choice that contradicts it is refused.
    A vehicle that announces ``MAV_AUTOPILOT_GENERIC`` (custom firmware) is flown with the mode
    layout chosen, PX4's by default in the rotors output; its parameters are not checked (the
    rules name PX4's and ArduCopter's parameters) and its telemetry rate is not capped. In the
    rates output a GENERIC vehicle needs the choice: whose thrust set-point it takes decides
    how the thrust is read, so mavreg does not guess."""
    if choice is not None and choice not in _LAYOUTS:
        return DialectChoice(None, f"dialect {choice!r}: expected one of {', '.join(_LAYOUTS)}")
    autopilot = int(hb.autopilot)
    if autopilot != M.MAV_AUTOPILOT_GENERIC:
        dialect = dialect_for(hb)
        if dialect is None:
            return DialectChoice(None, unsupported_reason(hb))
        if choice is not None and _LAYOUTS[choice] is not dialect:
            return DialectChoice(None, f"the vehicle announces {dialect.name} (autopilot {autopilot}) but the "
                                 f"dialect chosen is {choice}: remove the choice (--dialect or the vehicle "
                                 "file's dialect:), it is only for custom firmware that announces GENERIC (0)")
        return DialectChoice(dialect)
    if choice is None and output == "rates":
        return DialectChoice(None, "autopilot 0 (MAV_AUTOPILOT_GENERIC) in the rates output: mavreg cannot tell "
                             "whose mode numbers and thrust set-point it takes; choose with " + _CHOOSE)
    layout = _LAYOUTS[choice or "px4"]
    how = "as chosen" if choice is not None else "by default for the rotors output; change it with " + _CHOOSE
    notice = (f"autopilot 0 (MAV_AUTOPILOT_GENERIC): flying it with {layout.name}'s mode layout "
              f"({layout.offboard_mode} to fly, {layout.land_mode} to land) {how}; its parameters are not "
              "checked, its own offboard-loss failsafe is the operator's to set")
    return DialectChoice(replace(layout, name=f"GENERIC ({layout.name} modes)", rules=(), max_rate_hz=math.inf),
                         notice=notice)
