"""The emulator's autopilot as a sans-I/O state machine.

Decoded MAVLink messages and the simulation time go in; messages to send (pymavlink
message objects, packed by the link) and rotor commands come out. No sockets, no wall
clock: tests drive it directly.

Acceptance rules (documented in docs/firmware_sim.md):

- SET_ACTUATOR_CONTROL_TARGET: source system == ours; ``target_system`` == ours and
  ``target_component`` 0 or ours; the first component that sends a valid one becomes the
  offboard peer (a malformed target claims nothing), others are ``foreign_component``; ``group_mlx`` 0; all 8 controls
  finite (else ``non_finite``, whole message); controls 0..3 within [0, 1] +- 1e-6
  (else ``out_of_range``). A valid target keeps the stream alive; it is applied only
  while armed and in OFFBOARD (else counted ``not_armed_or_not_offboard``).
- COMMAND_LONG and COMMAND_INT: source system == ours or one of ``peer_system_ids`` (ground
  stations; none by default), any component; ``target_system`` ours (or 0 broadcast),
  ``target_component`` ours or 0; a parameter the command reads that is not finite:
  ``non_finite``, denied (ARM_DISARM's ``param2`` is read only to force a disarm: NaN there,
  as MAVSDK sends an unused parameter, is "not forced", as on PX4). The PX4 commands and
  the PARAM_* messages (same source and target rules) are :mod:`firmware_sim.px4_commands`.
- TIMESYNC: same source rule as COMMAND_LONG. A request (``tc1`` 0) is answered with
  ``tc1`` = our clock (sim time) in ns when it is handled and ``ts1`` echoed, as PX4
  does; a reply (``tc1`` != 0) sent to us is ``unsupported``, and so is every request with
  ``answer_timesync`` off (``--no-timesync``).
- SET_POSITION_TARGET_LOCAL_NED and SET_ATTITUDE_TARGET (body rates and thrust, source and
  target rules as SET_ACTUATOR_CONTROL_TARGET): :mod:`firmware_sim.setpoints`.
- HEARTBEAT from anyone is fine. Any other message is ``unsupported``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from . import modes
from .messages import state_messages
from .px4 import Px4Services
from .rate_loop import RateLoop, RateLoopConfig
from .setpoints import take_setpoint, take_target, target_content_reason
from .px4_commands import HANDLED, CommandInt, handle_command, handle_param
from .reboot import handle_reboot_command
from .stabilizer import Stabilizer

__all__ = ["AutopilotConfig", "Autopilot", "FORCE_DISARM_MAGIC", "DROP_REASONS", "OFFBOARD_TARGETS",
           "state_messages", "AUTOPILOTS"]

FORCE_DISARM_MAGIC = 21196.0
TAKEOFF_REACHED_M = 0.1
"""AUTO.TAKEOFF hands over to HOLD within this of the take-off height."""
DROP_REASONS = ("malformed", "foreign_system", "foreign_component", "wrong_target", "non_finite",
                "out_of_range", "not_armed_or_not_offboard", "unsupported")
OFFBOARD_TARGETS = ("SET_ACTUATOR_CONTROL_TARGET", "SET_ATTITUDE_TARGET")
"""The offboard peer's per-sample messages: rotor forces or body rates (the lockstep counts them)."""
AUTOPILOTS = {"px4": mavlink2.MAV_AUTOPILOT_PX4, "generic": mavlink2.MAV_AUTOPILOT_GENERIC}
"""What the HEARTBEAT may announce (``--autopilot``): PX4, or custom firmware (GENERIC) that
speaks PX4's mode layout, as a rotor-command vehicle of one's own might."""

_SEV_INFO = mavlink2.MAV_SEVERITY_INFO
_SEV_WARN = mavlink2.MAV_SEVERITY_WARNING
_SEV_CRIT = mavlink2.MAV_SEVERITY_CRITICAL
_ACCEPTED = mavlink2.MAV_RESULT_ACCEPTED
_DENIED = mavlink2.MAV_RESULT_DENIED
_TEMP_REJECTED = mavlink2.MAV_RESULT_TEMPORARILY_REJECTED
_UNSUPPORTED = mavlink2.MAV_RESULT_UNSUPPORTED
_COMMAND_PARAMS = {mavlink2.MAV_CMD_COMPONENT_ARM_DISARM: ("param1",),
                   mavlink2.MAV_CMD_DO_SET_MODE: ("param1", "param2", "param3"),
                   mavlink2.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: ("param1",)}
"""The parameters each handled command reads: a non-finite one is ``non_finite``, denied."""


@dataclass(frozen=True)
class AutopilotConfig:
    """Identity, timeouts and failsafe behaviour of the autopilot (SI, sim time)."""

    system_id: int = 1
    component_id: int = 1
    autopilot: int = mavlink2.MAV_AUTOPILOT_PX4
    """The HEARTBEAT's ``autopilot`` (:data:`AUTOPILOTS`); the modes are PX4's either way."""
    peer_system_ids: tuple = ()
    """COMMAND_LONG and TIMESYNC are also taken from these system ids (ground stations;
    the link's peer filter must admit them too, :mod:`firmware_sim.peers`)."""
    max_rotor_thrust_n: float = 12.0
    offboard_loss_timeout_s: float = 0.25
    failsafe_hold_s: float = 1.5
    land_descent_m_s: float = 0.7
    """Descent speed of LAND (PX4's ``MPC_LAND_SPEED`` default)."""
    land_disarm_s: float = 0.5
    """Time on the ground before the automatic disarm: in LAND, and in any mode but OFFBOARD
    once it has flown since arming (PX4's land detector and ``COM_DISARM_LAND``)."""
    stream_min_hz: float = 2.0
    stream_min_duration_s: float = 0.5
    heartbeat_period_s: float = 1.0
    max_arm_tilt_rad: float = math.radians(10.0)
    range_tolerance: float = 1e-6
    answer_timesync: bool = True
    """False: TIMESYNC requests are ignored (counted ``unsupported``), as by a vehicle that
    does not implement the protocol (``--no-timesync``)."""


class Autopilot:
    """Arming, modes, offboard stream tracking, failsafe and drop counters.

    Parameters
    ----------
    config : AutopilotConfig
    stabilizer : Stabilizer
        Flies HOLD and LAND.
    hover_thrust_n : float
        Per-rotor hover thrust: the held offboard command of an in-flight start until
        the first target arrives.
    px4 : Px4Services, optional
        Status streams, home, battery and parameters (default: a 500 Hz one).
    rate_loop : RateLoopConfig, optional
        The rate loop of OFFBOARD rate set-points (default gains).
    """

    def __init__(self, config: AutopilotConfig, stabilizer: Stabilizer, hover_thrust_n: float,
                 px4: Px4Services | None = None, rate_loop: RateLoopConfig | None = None):
        self.cfg = config
        self.px4 = px4 if px4 is not None else Px4Services()
        self.stab = stabilizer
        self.armed = False
        self.mode = modes.HOLD
        self.failsafe = False
        self.drops = dict.fromkeys(DROP_REASONS, 0)
        self.offboard_component: int | None = None
        self.target_count = 0           # valid targets received (the lockstep loop watches it)
        self.applied_count = 0
        self.target_n = (0.0, 0.0, 0.0, 0.0)
        self.last_target_t = -math.inf
        self.stream_start_t = math.inf
        self.mode_since_t = 0.0
        self.ground_since_t: float | None = None
        self.flown = False              # airborne since it was armed
        self.next_heartbeat_t = 0.0
        self.hover_thrust_n = float(hover_thrust_n)
        """Per-rotor hover thrust of the vehicle file (N)."""
        self._hover_n = (self.hover_thrust_n,) * 4
        self.rates = RateLoop(rate_loop or RateLoopConfig(), self.px4.rate_hz, config.max_rotor_thrust_n)
        self.rate_mode = False
        """Whether the last offboard set-point was a rate one (flown by :attr:`rates`)."""
        self.mask_warning_t = -math.inf
        self._out: list = []
        self._last_state = None
        self.setpoint = None
        """The last offboard position/velocity set-point; an actuator target clears it."""
        self.reboot_requested = False
        """A reboot command was accepted (the engine takes it: :mod:`firmware_sim.reboot`)."""

    # ---------------------------------------------------------------- state
    def start_in_flight(self, t_s: float) -> list:
        """Armed and in OFFBOARD at ``t_s`` (the ``--start`` case); hover held until a target."""
        self.armed = True
        self.target_n = self._hover_n
        self.last_target_t = t_s
        self.mode = modes.OFFBOARD
        self.mode_since_t = t_s
        return [self._statustext(_SEV_INFO, "started in flight: armed, OFFBOARD")]

    def _statustext(self, severity: int, text: str):
        return mavlink2.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0)

    def heartbeat(self):
        """HEARTBEAT describing the current mode and armed flag, as PX4 announces itself
        (``MAV_AUTOPILOT_PX4``: log tools and ground stations then name its modes), or as
        custom firmware does (``MAV_AUTOPILOT_GENERIC``, :attr:`AutopilotConfig.autopilot`)."""
        return mavlink2.MAVLink_heartbeat_message(
            mavlink2.MAV_TYPE_QUADROTOR, self.cfg.autopilot,
            modes.base_mode(self.armed), self.mode,
            mavlink2.MAV_STATE_ACTIVE if self.armed else mavlink2.MAV_STATE_STANDBY, 3)

    def _set_mode(self, mode: int, t_s: float, why: str, state=None, failsafe: bool = False):
        changed = mode != self.mode
        if changed and mode in (modes.HOLD, modes.LAND) and state is not None and \
                self.mode == modes.OFFBOARD:
            self.stab.reset(state)
        elif changed and mode == modes.HOLD and state is not None:
            self.stab.reset(state)
        self.mode = mode
        self.mode_since_t = t_s
        self.failsafe = failsafe
        sev = _SEV_WARN if failsafe else _SEV_INFO
        self._out.append(self._statustext(sev, f"mode {modes.MODE_NAMES[mode]}: {why}"))
        self._out.append(self.heartbeat())

    def deny(self, msg, why: str) -> None:
        """A STATUSTEXT saying ``why`` and a DENIED ack."""
        self._out.append(self._statustext(_SEV_WARN, why))
        self._ack(msg, _DENIED)

    def arming_ok(self, on_ground: bool, state=None) -> bool:
        """Whether an arm request would be accepted now (landed and level)."""
        s = state if state is not None else self._last_state
        if s is None:
            return on_ground
        tilt = math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (s[4] ** 2 + s[5] ** 2))))
        return on_ground and tilt <= self.cfg.max_arm_tilt_rad

    def _set_armed(self, armed: bool, why: str):
        self.armed, self.flown = armed, False
        if not armed:
            self.failsafe = False
        self._out.append(self._statustext(_SEV_INFO, f"{'armed' if armed else 'disarmed'}: {why}"))
        self._out.append(self.heartbeat())

    def stream_alive(self, t_s: float) -> bool:
        """Targets streaming at >= stream_min_hz for >= stream_min_duration_s (position
        set-points: one within 1 / stream_min_hz, as PX4 asks, so MAVSDK's offboard start works)."""
        gap = 1.0 / self.cfg.stream_min_hz
        if self.setpoint is not None or self.rate_mode:    # PX4's rule for set-points: a fresh one
            return t_s - self.last_target_t <= gap
        return (t_s - self.last_target_t <= gap
                and t_s - self.stream_start_t >= self.cfg.stream_min_duration_s - 1e-9)

    # ---------------------------------------------------------------- input
    def handle(self, msg, t_s: float, state, on_ground: bool) -> list:
        """Process one decoded message at sim time ``t_s``; return the replies."""
        self._out = []
        mtype = msg.get_type()
        if mtype in OFFBOARD_TARGETS:
            take_target(self, msg, t_s)
        elif mtype == "COMMAND_LONG":
            self._on_command(msg, t_s, state, on_ground)
        elif mtype == "SET_POSITION_TARGET_LOCAL_NED":
            take_setpoint(self, msg, t_s)
        elif mtype == "COMMAND_INT":
            self._on_command(CommandInt(msg), t_s, state, on_ground)
        elif mtype in ("PARAM_REQUEST_LIST", "PARAM_REQUEST_READ", "PARAM_SET"):
            if self._admit(msg):
                handle_param(self, msg)
        elif mtype == "TIMESYNC":
            self._on_timesync(msg, t_s)
        elif mtype == "BAD_DATA":
            self.drops["malformed"] += 1
        elif mtype != "HEARTBEAT":
            self.drops["unsupported"] += 1
        return self._out

    def target_drop_reason(self, msg) -> str | None:
        """Why an offboard target (:data:`OFFBOARD_TARGETS`) would be dropped now (``None``: valid).
        No side effect.

        Before any offboard peer is known, every component passes the component check.
        """
        cfg = self.cfg
        if msg.get_srcSystem() != cfg.system_id:
            return "foreign_system"
        if msg.target_system != cfg.system_id or msg.target_component not in (0, cfg.component_id):
            return "wrong_target"
        if self.offboard_component is not None and msg.get_srcComponent() != self.offboard_component:
            return "foreign_component"
        return target_content_reason(msg, cfg.range_tolerance)

    def _ack(self, msg, result: int):
        self._out.append(mavlink2.MAVLink_command_ack_message(
            msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))

    def _admit(self, msg) -> bool:
        """The source and target checks of commands and parameters (drops counted)."""
        cfg = self.cfg
        if msg.get_srcSystem() != cfg.system_id and msg.get_srcSystem() not in cfg.peer_system_ids:
            self.drops["foreign_system"] += 1
            return False
        if msg.target_system not in (0, cfg.system_id) or msg.target_component not in (0, cfg.component_id):
            self.drops["wrong_target"] += 1
            return False
        return True

    def _on_command(self, msg, t_s: float, state, on_ground: bool) -> None:
        if not self._admit(msg):
            return
        used = _COMMAND_PARAMS.get(msg.command, ())
        if not all(math.isfinite(getattr(msg, p)) for p in used):
            self.drops["non_finite"] += 1
            self._ack(msg, _DENIED)
            return
        if msg.command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
            self._arm_disarm(msg, t_s, state, on_ground)
        elif msg.command == mavlink2.MAV_CMD_DO_SET_MODE:
            self._do_set_mode(msg, t_s, state, on_ground)
        elif msg.command in HANDLED:
            handle_command(self, msg, t_s, state, on_ground)
        elif msg.command == mavlink2.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
            handle_reboot_command(self, msg)
        else:
            self.drops["unsupported"] += 1
            self._ack(msg, _UNSUPPORTED)

    def _on_timesync(self, msg, t_s: float) -> None:
        cfg = self.cfg
        if msg.get_srcSystem() != cfg.system_id and msg.get_srcSystem() not in cfg.peer_system_ids:
            self.drops["foreign_system"] += 1
            return
        if msg.tc1 != 0 or not cfg.answer_timesync:   # a reply (we send no request), or not answering
            self.drops["unsupported"] += 1
            return
        self._out.append(mavlink2.MAVLink_timesync_message(int(round(t_s * 1e9)), msg.ts1))

    def _arm_disarm(self, msg, t_s, state, on_ground) -> None:
        if msg.param1 == 1.0:
            if self.armed:
                self._ack(msg, _ACCEPTED)
                return
            if not self.arming_ok(on_ground, state):
                self._out.append(self._statustext(_SEV_WARN, "arming denied: not landed and level"))
                self._ack(msg, _DENIED)
                return
            self._ack(msg, _ACCEPTED)
            self.px4.set_home(state[0:3])       # PX4 sets home where it arms
            self._set_armed(True, "by command")
        elif msg.param1 == 0.0:
            if not self.armed:
                self._ack(msg, _ACCEPTED)
                return
            if not on_ground and msg.param2 != FORCE_DISARM_MAGIC:
                self._out.append(self._statustext(_SEV_WARN, "disarm denied: in flight (param2=21196 forces)"))
                self._ack(msg, _DENIED)
                return
            self._ack(msg, _ACCEPTED)
            self._set_armed(False, "forced in flight" if not on_ground else "by command")
        else:
            self._out.append(self._statustext(_SEV_WARN, "arm/disarm denied: param1 must be 0 or 1"))
            self._ack(msg, _DENIED)

    def _do_set_mode(self, msg, t_s, state, on_ground) -> None:
        if not (int(msg.param1) & modes.BASE_MODE_CUSTOM):
            self._out.append(self._statustext(_SEV_WARN, "mode denied: param1 needs custom mode (1)"))
            self._ack(msg, _DENIED)
            return
        main, sub = int(msg.param2), int(msg.param3)
        if main == modes.MAIN_OFFBOARD:
            if not self.stream_alive(t_s):
                self._out.append(self._statustext(_SEV_WARN, "OFFBOARD denied: no actuator target stream"))
                self._ack(msg, _DENIED)
                return
            new = modes.OFFBOARD
        elif main == modes.MAIN_AUTO and sub == modes.SUB_AUTO_LOITER:
            new = modes.HOLD
        elif main == modes.MAIN_AUTO and sub == modes.SUB_AUTO_LAND:
            new = modes.LAND
        else:
            self._out.append(self._statustext(_SEV_WARN, f"mode denied: unsupported mode {main}.{sub}"))
            self._ack(msg, _DENIED)
            return
        self._ack(msg, _ACCEPTED)
        if new != self.mode:
            self._set_mode(new, t_s, "by command", state)

    # ---------------------------------------------------------------- periodic
    def update(self, t_s: float, state, on_ground: bool) -> list:
        """Timeouts, failsafe phases, landing detection and heartbeat at ``t_s``."""
        self._out = []
        self._last_state = state
        cfg = self.cfg
        if (self.mode == modes.TAKEOFF and not on_ground
                and abs(state[2] - self.stab.z_ref_m) < TAKEOFF_REACHED_M):
            self._set_mode(modes.HOLD, t_s, "takeoff done", state)
        if self.mode == modes.OFFBOARD and t_s - self.last_target_t > cfg.offboard_loss_timeout_s + 1e-9:
            if self.armed and not on_ground:
                self._set_mode(modes.HOLD, t_s, "offboard lost, failsafe hold", state, failsafe=True)
            else:
                self._set_mode(modes.HOLD, t_s, "offboard lost", state)
        if self.failsafe and self.mode == modes.HOLD and t_s - self.mode_since_t >= cfg.failsafe_hold_s - 1e-9:
            self._set_mode(modes.LAND, t_s, "failsafe land", state, failsafe=True)
        if on_ground:
            if self.ground_since_t is None:
                self.ground_since_t = t_s
        else:
            self.ground_since_t, self.flown = None, self.flown or self.armed
        if (self.armed and (self.mode == modes.LAND or (self.flown and self.mode != modes.OFFBOARD))
                and self.ground_since_t is not None and t_s - self.ground_since_t >= cfg.land_disarm_s - 1e-9):
            self._set_armed(False, "landed")
            self._set_mode(modes.HOLD, t_s, "landed")
        if t_s >= self.next_heartbeat_t - 1e-9:
            self._out.append(self.heartbeat())
            self.next_heartbeat_t = t_s + cfg.heartbeat_period_s
        return self._out

    def rotor_command_n(self, state, on_ground: bool, t_s: float | None = None, gyro_rad_s=None):
        """Rotor thrusts (N) the autopilot commands for the coming control period (at ``t_s``;
        ``gyro_rad_s`` the published body rates the rate loop flies on, default the true ones)."""
        if not self.armed:
            return (0.0, 0.0, 0.0, 0.0)
        if self.mode == modes.OFFBOARD:
            cmd = None if not self.rate_mode else \
                self.rates.command_n(t_s, state[10:13] if gyro_rad_s is None else gyro_rad_s, on_ground)
            if cmd is not None:
                return cmd
            sp = self.setpoint       # and within the latency of a first rate set-point
            return self.target_n if sp is None else self.stab.track(state, sp.position_ned, sp.velocity_ned, sp.yaw_rad)
        if self.mode == modes.TAKEOFF:
            return self.stab.hold(state)    # climbs to the take-off height, from the ground too
        if on_ground:
            return (0.0, 0.0, 0.0, 0.0)     # idle on the ground in HOLD and LAND
        if self.mode == modes.LAND:
            return self.stab.land(state, self.cfg.land_descent_m_s)
        return self.stab.hold(state)
