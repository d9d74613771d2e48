"""Does the daemon's stream set-up fit a serial line? Bytes per second against the baud (pure).

The daemon asks the autopilot for ATTITUDE_QUATERNION and LOCAL_POSITION_NED at the control
rate and EXTENDED_SYS_STATE at 5 Hz (:meth:`mavreg.daemon.vehicle.autopilots.Dialect.telemetry_requests`,
the very requests it sends), and hears a HEARTBEAT a second and a TIMESYNC reply for each of
its 10 Hz requests. It sends one command a period (SET_ACTUATOR_CONTROL_TARGET in the rotors
output, SET_ATTITUDE_TARGET in the rates output), the TIMESYNC requests and its HEARTBEAT.

Each message costs a MAVLink 2 frame of its whole payload (the worst case: trailing zeros
are trimmed on the wire, never counted off here): 10 header bytes, the payload, 2 CRC bytes,
13 more when signed. A UART sends 10 bits a byte (start, 8 data, stop), and a line is only
trusted to :data:`LINE_SHARE` of its speed (the autopilot's own streams, retries, a slow
reader). The line is full duplex: each direction is judged on its own, and the busier one
decides. A TCP link has no baud and is not judged.
"""
from __future__ import annotations

import math
from typing import NamedTuple

from pymavlink.dialects.v20 import common as M

from .autopilots import PX4

__all__ = ["LinkBudget", "frame_bytes", "link_budget", "baud_refusal", "UART_BITS_PER_BYTE", "LINE_SHARE"]

UART_BITS_PER_BYTE = 10
"""Start bit, 8 data bits, stop bit (8N1)."""
LINE_SHARE = 0.8
"""The share of the line's speed the daemon's own streams may take (a 25 % margin)."""
HEADER_CRC_BYTES = 12
SIGNATURE_BYTES = 13
HEARTBEAT_HZ = 1.0
"""The daemon's HEARTBEAT (``mavreg.daemon.jobs.app.HEARTBEAT_S``) and the vehicle's."""
TIMESYNC_HZ = 10.0
"""The daemon's TIMESYNC requests and the vehicle's replies
(:attr:`mavreg.daemon.vehicle.timesync.TimesyncEstimator.request_period_s`, 0.1 s)."""
COMMAND_ID = {"rotors": M.MAVLINK_MSG_ID_SET_ACTUATOR_CONTROL_TARGET,
              "rates": M.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET}


class LinkBudget(NamedTuple):
    down_bytes_per_s: float
    """Vehicle to daemon."""
    up_bytes_per_s: float
    """Daemon to vehicle."""

    @property
    def needed_baud_bps(self) -> float:
        """The baud that carries the busier direction within :data:`LINE_SHARE`."""
        return max(self.down_bytes_per_s, self.up_bytes_per_s) * UART_BITS_PER_BYTE / LINE_SHARE


def frame_bytes(msg_id: int, signed: bool = False) -> int:
    """Bytes of one MAVLink 2 frame of ``msg_id`` with its whole payload."""
    payload = M.mavlink_map[msg_id].unpacker.size
    return HEADER_CRC_BYTES + payload + (SIGNATURE_BYTES if signed else 0)


def _downlink_rates_hz(telemetry_rate_hz: float) -> dict[int, float]:
    """Message id -> Hz the daemon's SET_MESSAGE_INTERVAL requests ask for (PX4: no rate cap)."""
    rates = {}
    for cmd in PX4.telemetry_requests(1, 1, telemetry_rate_hz):
        rates[int(cmd.param1)] = 1e6 / cmd.param2
    rates[M.MAVLINK_MSG_ID_HEARTBEAT] = HEARTBEAT_HZ
    rates[M.MAVLINK_MSG_ID_TIMESYNC] = TIMESYNC_HZ
    return rates


def link_budget(telemetry_rate_hz: float, output: str = "rotors", signed: bool = False) -> LinkBudget:
    """Bytes per second each way for telemetry and commands at ``telemetry_rate_hz``."""
    down = sum(hz * frame_bytes(mid, signed) for mid, hz in _downlink_rates_hz(telemetry_rate_hz).items())
    up = (telemetry_rate_hz * frame_bytes(COMMAND_ID[output], signed)
          + TIMESYNC_HZ * frame_bytes(M.MAVLINK_MSG_ID_TIMESYNC, signed)
          + HEARTBEAT_HZ * frame_bytes(M.MAVLINK_MSG_ID_HEARTBEAT, signed))
    return LinkBudget(down, up)


def _highest_rate_hz(baud_bps: int, output: str, signed: bool) -> float:
    """The highest telemetry rate whose budget fits ``baud_bps`` (the budget is affine in the
    rate above the 5 Hz of EXTENDED_SYS_STATE: fitted on 10 and 20 Hz)."""
    b10, b20 = link_budget(10.0, output, signed), link_budget(20.0, output, signed)
    room = baud_bps * LINE_SHARE / UART_BITS_PER_BYTE
    best = math.inf
    for lo, hi in zip(b10, b20):
        per_hz = (hi - lo) / 10.0
        best = min(best, (room - (lo - 10.0 * per_hz)) / per_hz)
    return max(best, 0.0)


def baud_refusal(baud_bps: int, telemetry_rate_hz: float, output: str = "rotors", signed: bool = False,
                 name: str = "the serial link") -> str | None:
    """One line refusing a line too slow for the streams at ``telemetry_rate_hz``, else None."""
    budget = link_budget(telemetry_rate_hz, output, signed)
    need = budget.needed_baud_bps
    if need <= baud_bps:
        return None
    return (f"{name} at {baud_bps} baud is too slow for {telemetry_rate_hz:g} Hz of attitude and position: "
            f"the telemetry needs {budget.down_bytes_per_s:,.0f} B/s and the commands "
            f"{budget.up_bytes_per_s:,.0f} B/s, {need:,.0f} baud at {UART_BITS_PER_BYTE} bits a byte with a "
            f"{100 * (1 / LINE_SHARE - 1):.0f} % margin: set the port and the autopilot to 921600 "
            f"(PX4 SER_TEL2_BAUD, ArduPilot SERIAL2_BAUD 921) or lower --control-rate-hz to "
            f"{math.floor(_highest_rate_hz(baud_bps, output, signed)):d} or less")
