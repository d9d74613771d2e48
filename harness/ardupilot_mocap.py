"""A motion-capture feed for the ArduCopter SITL: its true pose at 100 Hz, sent back as vision.

What aggressive-flight rigs give the autopilot is a motion-capture system: the pose at 100+ Hz
with a few milliseconds of latency. The SITL's own ``sim:vicon:`` device is no such thing (it
holds each message a random 25-124 ms). :class:`MocapFeed` is one: on the SITL's second MAVLink
port (SERIAL1) it asks for ``SIM_STATE`` (the physics' true state) at :data:`FEED_RATE_HZ` and
answers each with ``VISION_POSITION_ESTIMATE`` (NED position about :data:`HOME`, roll, pitch,
yaw) and ``VISION_SPEED_ESTIMATE`` (NED velocity) at once. EKF3 fuses them as ExternalNav
(``VISO_TYPE`` 1, ``ardupilot_mocap.parm``).

Time stamps: ArduPilot maps ``usec`` onto its own clock by the least transport lag it has seen
(its ``JitterCorrection``), after subtracting the time the bytes would take at the port's
``SERIALn_BAUD`` (``receive_time_constraint_us``); EKF3 then places the sample ``VISO_DELAY_MS``
earlier still. So the stamp's clock does not matter (the host's monotonic clock at the moment
``SIM_STATE`` arrived), but the baud does: at SERIAL1's default 57600, 129 bytes are 22 ms,
and the EKF put every sample that much too early and ran ahead of the truth (docs/autopilots.md).
"""
from __future__ import annotations

import math
import threading
import time

from pymavlink import mavutil

__all__ = ["MocapFeed", "ned_m", "vision_sample", "HOME", "EARTH_RADIUS_M", "FEED_RATE_HZ"]

M = mavutil.mavlink
EARTH_RADIUS_M = 6378137.0
HOME = (-35.363261, 149.165230, 584.0)
"""start.sh's default home (lat, lon deg, alt m): the origin of the vision frame (the GPS sets
the EKF origin about 9 cm higher)."""
FEED_RATE_HZ = 100.0


def ned_m(lat_deg: float, lon_deg: float, alt_m: float, origin: tuple[float, float, float]) -> tuple:
    """North, east, down (m) of a point about ``origin`` (lat, lon deg, alt m); flat earth."""
    lat0, lon0, alt0 = origin
    north = math.radians(lat_deg - lat0) * EARTH_RADIUS_M
    east = math.radians(lon_deg - lon0) * EARTH_RADIUS_M * math.cos(math.radians(lat0))
    return north, east, -(alt_m - alt0)


def vision_sample(sim_state, origin: tuple[float, float, float] = HOME) -> dict:
    """The vision messages' fields from one ``SIM_STATE``: ``position_m`` (NED about ``origin``),
    ``euler_rad`` (roll, pitch, yaw) and ``velocity_m_s`` (NED). The 1e-7 deg integer latitude
    and longitude when the message has them (the float ones resolve only ~0.4 m)."""
    lat = sim_state.lat_int * 1e-7 if getattr(sim_state, "lat_int", 0) else sim_state.lat
    lon = sim_state.lon_int * 1e-7 if getattr(sim_state, "lon_int", 0) else sim_state.lon
    return {"position_m": ned_m(lat, lon, sim_state.alt, origin),
            "euler_rad": (sim_state.roll, sim_state.pitch, sim_state.yaw),
            "velocity_m_s": (sim_state.vn, sim_state.ve, sim_state.vd)}


class MocapFeed:
    """A thread that turns the SITL's ``SIM_STATE`` into vision messages, on its own port.

    Parameters
    ----------
    port : int
        The UDP port the SITL's SERIAL1 sends to (``udpclient``); the feed listens there.
    rate_hz : float
        ``SIM_STATE`` rate asked for; one pair of vision messages per ``SIM_STATE``.
    clock_s : callable
        Monotonic seconds, the ``usec`` stamp (ArduPilot re-maps it; see the module's notes).
    """

    def __init__(self, port: int, rate_hz: float = FEED_RATE_HZ, clock_s=time.monotonic):
        self.port, self.rate_hz, self.clock_s = int(port), float(rate_hz), clock_s
        self.sent = 0
        """Pairs of vision messages sent."""
        self._conn = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Listen on the port and start feeding (the rate is asked for once the SITL speaks)."""
        self._conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{self.port}", source_system=255,
                                                source_component=M.MAV_COMP_ID_VISUAL_INERTIAL_ODOMETRY,
                                                dialect="ardupilotmega")
        self._thread = threading.Thread(target=self._run, name="mocap-feed", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the thread and close the port."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def _run(self) -> None:
        asked_s = -math.inf
        last_state_s = -math.inf
        while not self._stop.is_set():
            m = self._conn.recv_match(blocking=True, timeout=0.05)
            now = self.clock_s()
            if m is not None and m.get_type() == "SIM_STATE":
                last_state_s = now
                self._send(m, now)
            elif now - last_state_s > 1.0 and now - asked_s > 1.0 and m is not None:
                # the SITL speaks on this port but sends no SIM_STATE (yet): ask for it
                asked_s = now
                self._conn.mav.command_long_send(m.get_srcSystem(), 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                                 M.MAVLINK_MSG_ID_SIM_STATE, 1e6 / self.rate_hz, 0, 0, 0, 0, 0)

    def _send(self, sim_state, now_s: float) -> None:
        s = vision_sample(sim_state)
        usec = int(now_s * 1e6)
        (x, y, z), (roll, pitch, yaw), vel = s["position_m"], s["euler_rad"], s["velocity_m_s"]
        nan21 = [math.nan] * 21
        self._conn.mav.vision_position_estimate_send(usec, x, y, z, roll, pitch, yaw, nan21, 0)
        self._conn.mav.vision_speed_estimate_send(usec, *vel, [math.nan] * 9, 0)
        self.sent += 1
