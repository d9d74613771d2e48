"""What a ground station or MAVSDK expects of a PX4 vehicle: status messages, streams, parameters.

Sans-I/O, like the autopilot: the engine calls :meth:`Px4Services.periodic` once per control
period with the published state and gets the messages that are due; the autopilot hands it
``PARAM_*`` messages and the commands of :data:`firmware_sim.px4_commands.HANDLED`.

- **Home and global position.** The local NED origin (the take-off spot of the ground start)
  is at :attr:`Px4Config.origin_lat_deg`, ``origin_lon_deg``, ``origin_alt_m`` (by default
  PX4 SITL's default home, Zurich airfield, 488 m AMSL). A local position converts to
  latitude/longitude on a flat earth around the origin (``lat = lat0 + north / R``,
  ``lon = lon0 + east / (R cos lat0)``, R = 6 371 000 m; under 1 mm error within 1 km) and
  ``alt = alt0 - down``. Home is the origin at start and is moved to the vehicle's position
  at each arming, as PX4 does.
- **Battery model** (it does not act on the physics; ``--thrust-scale`` does that): a
  4-cell LiPo of ``battery_capacity_mah``, drawing ``idle_current_a`` plus
  ``current_a_per_n`` per newton of applied rotor thrust; the charge used integrates that
  current; the open-circuit voltage falls linearly from 4.2 to 3.5 V a cell with the charge
  left, less ``internal_resistance_ohm`` times the current.
- **Sensors.** The simulated gyro, accelerometer, magnetometer, barometer and GPS are always
  present, enabled and healthy, and so are the controllers; the pre-arm check bit is
  healthy while arming would be accepted (disarmed on the ground and level, or armed).
- **Landed state** (EXTENDED_SYS_STATE): ON_GROUND while the simulation has ground contact;
  in the air TAKEOFF while in the take-off mode and climbing, LANDING in LAND, else IN_AIR.
- **Streams**: :data:`DEFAULT_RATES_HZ`; ``None`` there means every control period (the
  state messages the daemon flies on). ``MAV_CMD_SET_MESSAGE_INTERVAL`` changes any of them
  (an interval shorter than a control period gives every period).
- **Parameters** (all REAL32, :data:`PARAMS`): the ones the emulator has, under PX4's names:
  the autopilot's settings, the rate loop's gains, filters and thrust model
  (:mod:`firmware_sim.rate_loop`), and ``MPC_THR_HOVER``, read only, computed from the
  vehicle file and ``THR_MDL_FAC``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from . import modes
from .messages import state_messages
from .physics import euler_from_quat
from .rate_loop import thrust_for_force

__all__ = ["Px4Config", "Px4Services", "Param", "PARAMS", "DEFAULT_RATES_HZ", "CAPABILITIES",
           "SENSORS", "EARTH_RADIUS_M", "landed_state"]

EARTH_RADIUS_M = 6371000.0
M = mavlink2
ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED = 30, 31, 32
STATE_IDS = (ATTITUDE, ATTITUDE_QUATERNION, LOCAL_POSITION_NED)
DEFAULT_RATES_HZ = {M.MAVLINK_MSG_ID_SYS_STATUS: 2.0, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 5.0,
                    M.MAVLINK_MSG_ID_HOME_POSITION: 0.5, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 50.0,
                    ATTITUDE: None, ATTITUDE_QUATERNION: None, LOCAL_POSITION_NED: None}
"""Stream rates (Hz) at start; ``None``: every control period."""
SENSORS = (M.MAV_SYS_STATUS_SENSOR_3D_GYRO | M.MAV_SYS_STATUS_SENSOR_3D_ACCEL
           | M.MAV_SYS_STATUS_SENSOR_3D_MAG | M.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
           | M.MAV_SYS_STATUS_SENSOR_GPS | M.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
           | M.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION | M.MAV_SYS_STATUS_SENSOR_YAW_POSITION
           | M.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL | M.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
           | M.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | M.MAV_SYS_STATUS_AHRS | M.MAV_SYS_STATUS_PREARM_CHECK)
CAPABILITIES = (M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT | M.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
                | M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT | M.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | M.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET)
"""What is true of the emulator: float parameters (all REAL32, so both encodings agree),
COMMAND_INT, MAVLink 2, SET_ATTITUDE_TARGET (body rates and thrust, from the offboard peer).
No missions, no FTP."""
OFFBOARD_LOSS_HOLD = 5.0
"""PX4's COM_OBL_RC_ACT value for what the emulator does when offboard set-points stop: Hold."""
FIRMWARE_VERSION = (0 << 24) | (1 << 16) | (0 << 8) | 255     # 0.1.0, official release type


@dataclass(frozen=True)
class Px4Config:
    """The PX4-facing side of the emulator (see the module docstring; SI unless named)."""

    origin_lat_deg: float = 47.397742
    origin_lon_deg: float = 8.545594
    origin_alt_m: float = 488.0
    battery_cells: int = 4
    battery_capacity_mah: float = 5000.0
    idle_current_a: float = 0.5
    current_a_per_n: float = 1.2
    internal_resistance_ohm: float = 0.02
    cell_full_v: float = 4.2
    cell_empty_v: float = 3.5


@dataclass(frozen=True)
class Param:
    """One parameter: PX4's name, what it is, its bounds and the autopilot setting it maps to."""

    name: str
    what: str
    low: float
    high: float
    attribute: str
    """An :class:`firmware_sim.autopilot.AutopilotConfig` field, ``rates.`` and a
    :class:`firmware_sim.rate_loop.RateLoopConfig` field, ``takeoff_height_m`` of
    :class:`Px4Services`, or ``hover_thrust`` (read only)."""
    read_only: bool = False


def _rate_params() -> tuple:
    """The rate loop's gains under PX4's names (normalized torque, :mod:`firmware_sim.rate_loop`)."""
    out = []
    for axis, px4 in (("roll", "ROLLRATE"), ("pitch", "PITCHRATE"), ("yaw", "YAWRATE")):
        for k, what, high in (("P", "per rad/s", 10.0), ("I", "per rad", 10.0),
                              ("D", "per rad/s^2", 0.1), ("FF", "per rad/s", 10.0)):
            out.append(Param(f"MC_{px4}_{k}", f"{axis} rate {k}, normalized torque {what}", 0.0, high,
                             f"rates.{axis}_{k.lower()}"))
    for axis, px4 in (("roll", "RR"), ("pitch", "PR"), ("yaw", "YR")):
        out.append(Param(f"MC_{px4}_INT_LIM", f"{axis} rate integrator limit, normalized torque", 0.0, 1.0,
                         f"rates.{axis}_int_lim"))
    return tuple(out)


PARAMS = (
    Param("COM_OF_LOSS_T", "offboard loss timeout, s (--offboard-loss-timeout)", 0.01, 60.0,
          "offboard_loss_timeout_s"),
    Param("COM_DISARM_LAND", "time on the ground before the automatic disarm (LAND; after a flight, any mode but OFFBOARD), s", 0.0, 20.0, "land_disarm_s"),
    Param("MIS_TAKEOFF_ALT", "take-off height above home, m", 0.5, 100.0, "takeoff_height_m"),
    Param("MPC_LAND_SPEED", "descent speed in LAND, m/s", 0.2, 3.0, "land_descent_m_s"),
    *_rate_params(),
    Param("IMU_GYRO_CUTOFF", "rate loop gyro low-pass, Hz (0 or >= half the loop rate: none)", 0.0, 1000.0,
          "rates.gyro_cutoff_hz"),
    Param("IMU_DGYRO_CUTOFF", "rate loop D-term low-pass, Hz (as above)", 0.0, 1000.0, "rates.dgyro_cutoff_hz"),
    Param("THR_MDL_FAC", "thrust model e: F = 4 f_max ((1 - e) t + e t^2)", 0.0, 1.0, "rates.thr_mdl_fac"),
    Param("MPC_THR_HOVER", "hover collective of the vehicle file under THR_MDL_FAC (read only)", 0.0, 1.0,
          "hover_thrust", read_only=True),
    Param("COM_OBL_RC_ACT", "offboard-loss action: 5 = Hold (then LAND: the failsafe; read only)", 0.0, 7.0,
          "offboard_loss_action", read_only=True),
)
"""The parameters, in index order (all MAV_PARAM_TYPE_REAL32)."""


def landed_state(on_ground: bool, mode: int, vz_m_s: float) -> int:
    """MAV_LANDED_STATE from ground contact, the mode and the vertical speed (NED, down +)."""
    if on_ground:
        return M.MAV_LANDED_STATE_ON_GROUND
    if mode == modes.TAKEOFF and vz_m_s < 0.0:
        return M.MAV_LANDED_STATE_TAKEOFF
    if mode == modes.LAND:
        return M.MAV_LANDED_STATE_LANDING
    return M.MAV_LANDED_STATE_IN_AIR


class Px4Services:
    """Streams, home, battery and parameters (see the module docstring).

    Parameters
    ----------
    config : Px4Config
    rate_hz : int
        The control rate: the fastest any stream goes.
    """

    def __init__(self, config: Px4Config | None = None, rate_hz: int = 500):
        self.cfg = config if config is not None else Px4Config()
        self.rate_hz = int(rate_hz)
        self.home_ned = (0.0, 0.0, 0.0)
        self.takeoff_height_m = 2.5
        self.used_mah = 0.0
        self.current_a = self.cfg.idle_current_a
        self._last_t: float | None = None
        self.interval_periods: dict = {}
        for msg_id, hz in DEFAULT_RATES_HZ.items():
            self.set_rate(msg_id, hz)
        self._next: dict = dict.fromkeys(self.interval_periods, 0)
        self.last = None
        """``(t, position, velocity, quat, rates)`` published last (what a request answers from)."""

    # ---------------------------------------------------------------- streams
    def set_rate(self, msg_id: int, hz: float | None) -> None:
        """Stream ``msg_id`` at ``hz`` (``None``: every period; 0: off)."""
        if hz is None:
            self.interval_periods[msg_id] = 1
        elif hz <= 0:
            self.interval_periods[msg_id] = 0
        else:
            self.interval_periods[msg_id] = max(1, int(round(self.rate_hz / hz)))

    def set_interval_us(self, msg_id: int, interval_us: float) -> None:
        """MAV_CMD_SET_MESSAGE_INTERVAL: -1 off, 0 default, else the interval (us)."""
        if interval_us == 0:
            self.set_rate(msg_id, DEFAULT_RATES_HZ[msg_id])
        elif interval_us < 0:
            self.set_rate(msg_id, 0.0)
        else:
            self.set_rate(msg_id, 1e6 / interval_us)
        self._next[msg_id] = 0

    def rate_hz_of(self, msg_id: int) -> float:
        """The stream rate of ``msg_id`` now (Hz; 0 off)."""
        n = self.interval_periods[msg_id]
        return self.rate_hz / n if n else 0.0

    def due(self, msg_id: int, period: int) -> bool:
        """Whether ``msg_id`` goes out in control period ``period`` (and schedule the next)."""
        n = self.interval_periods[msg_id]
        if n == 0 or period < self._next[msg_id]:
            return False
        self._next[msg_id] = period + n
        return True

    def periodic(self, period: int, t_s: float, pos, vel, quat, rates, ap, on_ground: bool,
                 applied_n) -> list:
        """The status messages due in ``period`` (not the state messages: :meth:`due`)."""
        self._battery(t_s, applied_n, ap.armed)
        self.last = (t_s, tuple(pos), tuple(vel), tuple(quat), tuple(rates))
        out = []
        for msg_id in (M.MAVLINK_MSG_ID_SYS_STATUS, M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
                       M.MAVLINK_MSG_ID_HOME_POSITION, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT):
            if self.due(msg_id, period):
                out.append(self.message(msg_id, ap, on_ground))
        return out

    def message(self, msg_id: int, ap, on_ground: bool):
        """The message ``msg_id`` now, or ``None`` when the emulator does not make it."""
        if msg_id == M.MAVLINK_MSG_ID_SYS_STATUS:
            return self.sys_status(ap, on_ground)
        if msg_id == M.MAVLINK_MSG_ID_EXTENDED_SYS_STATE:
            vz = self.last[2][2] if self.last is not None else 0.0
            return M.MAVLink_extended_sys_state_message(
                M.MAV_VTOL_STATE_UNDEFINED, landed_state(on_ground, ap.mode, vz))
        if msg_id == M.MAVLINK_MSG_ID_HOME_POSITION:
            return self.home_position()
        if msg_id == M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT:
            return self.global_position()
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return self.autopilot_version(ap.cfg.system_id)
        if msg_id == M.MAVLINK_MSG_ID_HEARTBEAT:
            return ap.heartbeat()
        if msg_id in STATE_IDS and self.last is not None:
            return state_messages(*self.last)[STATE_IDS.index(msg_id)]
        return None

    # ---------------------------------------------------------------- messages
    def _battery(self, t_s: float, applied_n, armed: bool) -> None:
        c = self.cfg
        self.current_a = c.idle_current_a + (c.current_a_per_n * sum(applied_n) if armed else 0.0)
        if self._last_t is not None and t_s > self._last_t:
            self.used_mah += self.current_a * (t_s - self._last_t) / 3.6
        self._last_t = t_s

    def battery_remaining(self) -> float:
        """Charge left, 0..1."""
        return max(0.0, 1.0 - self.used_mah / self.cfg.battery_capacity_mah)

    def battery_voltage_v(self) -> float:
        c = self.cfg
        cell = c.cell_empty_v + (c.cell_full_v - c.cell_empty_v) * self.battery_remaining()
        return max(0.0, c.battery_cells * cell - c.internal_resistance_ohm * self.current_a)

    def sys_status(self, ap, on_ground: bool):
        armable = ap.armed or ap.arming_ok(on_ground)
        health = SENSORS if armable else SENSORS & ~M.MAV_SYS_STATUS_PREARM_CHECK
        return M.MAVLink_sys_status_message(
            SENSORS, SENSORS, health, 0, int(round(self.battery_voltage_v() * 1000.0)),
            int(round(self.current_a * 100.0)), int(round(100.0 * self.battery_remaining())),
            0, 0, 0, 0, 0, 0)

    def to_global(self, ned) -> tuple:
        """``(lat_deg, lon_deg, alt_m)`` of a local NED position (flat earth around the origin)."""
        c = self.cfg
        lat = c.origin_lat_deg + math.degrees(ned[0] / EARTH_RADIUS_M)
        lon = c.origin_lon_deg + math.degrees(ned[1] / (EARTH_RADIUS_M * math.cos(math.radians(c.origin_lat_deg))))
        return lat, lon, c.origin_alt_m - ned[2]

    def set_home(self, ned) -> None:
        self.home_ned = tuple(float(x) for x in ned)

    def home_position(self):
        lat, lon, alt = self.to_global(self.home_ned)
        x, y, z = self.home_ned
        return M.MAVLink_home_position_message(
            int(round(lat * 1e7)), int(round(lon * 1e7)), int(round(alt * 1000.0)), x, y, z,
            (1.0, 0.0, 0.0, 0.0), 0.0, 0.0, 0.0, 0)

    def global_position(self):
        t, pos, vel, q, _ = self.last if self.last is not None else (0.0, (0.0,) * 3, (0.0,) * 3, (1.0, 0, 0, 0), None)
        lat, lon, alt = self.to_global(pos)
        hdg = math.degrees(euler_from_quat(q)[2]) % 360.0
        return M.MAVLink_global_position_int_message(
            int(round(t * 1000.0)), int(round(lat * 1e7)), int(round(lon * 1e7)),
            int(round(alt * 1000.0)), int(round((self.home_ned[2] - pos[2]) * 1000.0)),
            *(int(round(max(-3e4, min(3e4, v * 100.0)))) for v in vel), int(round(hdg * 100.0)) % 36000)

    def autopilot_version(self, system_id: int):
        return M.MAVLink_autopilot_version_message(
            CAPABILITIES, FIRMWARE_VERSION, 0, 0, 0, b"fsim\0\0\0\0", [0] * 8, [0] * 8, 0, 0,
            0x46534D0000000000 | system_id)

    # ---------------------------------------------------------------- parameters
    def param_get(self, ap, p: Param) -> float:
        """The value of parameter ``p`` now."""
        a = p.attribute
        if a == "takeoff_height_m":
            return self.takeoff_height_m
        if a == "offboard_loss_action":
            return OFFBOARD_LOSS_HOLD
        if a == "hover_thrust":
            return thrust_for_force(4.0 * ap.hover_thrust_n, ap.rates.cfg.thr_mdl_fac, ap.cfg.max_rotor_thrust_n)
        if a.startswith("rates."):
            return getattr(ap.rates.cfg, a[len("rates."):])
        return getattr(ap.cfg, a)

    def param_value(self, ap, index: int):
        p = PARAMS[index]
        value = self.param_get(ap, p)
        return M.MAVLink_param_value_message(p.name.encode(), float(value), M.MAV_PARAM_TYPE_REAL32,
                                             len(PARAMS), index)

    def param_index(self, name) -> int | None:
        """Index of the parameter ``name`` (bytes or str, NUL-padded), or ``None``."""
        if isinstance(name, (bytes, bytearray)):
            name = bytes(name).split(b"\0", 1)[0].decode("ascii", "replace")
        name = str(name).split("\0", 1)[0]
        for i, p in enumerate(PARAMS):
            if p.name == name:
                return i
        return None

    def set_param(self, ap, index: int, value: float) -> bool:
        """Set parameter ``index`` when ``value`` is finite and in bounds and it is not read
        only; ``False`` otherwise."""
        import dataclasses
        p = PARAMS[index]
        if p.read_only or not (math.isfinite(value) and p.low <= value <= p.high):
            return False
        if p.attribute == "takeoff_height_m":
            self.takeoff_height_m = float(value)
        elif p.attribute.startswith("rates."):
            field = p.attribute[len("rates."):]
            ap.rates.configure(dataclasses.replace(ap.rates.cfg, **{field: float(value)}))
        else:
            ap.cfg = dataclasses.replace(ap.cfg, **{p.attribute: float(value)})
        return True
