"""The two receive paths under test, each with the property checks of one input.

- :class:`DaemonTarget`: the daemon's link (:class:`mavreg.daemon.vehicle.link.FastLink`, or the
  reference :class:`~mavreg.daemon.vehicle.link_reference.MavlinkLink`) parsing a datagram and handing each
  message to a :class:`mavreg.daemon.flight.supervisor.Supervisor` (state assembly, vehicle status,
  TIMESYNC, acks), as the daemon wires them.
- :class:`VehicleTarget`: firmware_sim as its command line builds it (ideal world), fed
  through its UDP socket on loopback: :meth:`firmware_sim.link.Link.recv_datagram`, the
  engine and the autopilot.

:meth:`feed` returns a list of findings (empty: the input was handled as it must be):
an exception that escaped, an input that took more than ``STALL_S`` (a hang, not a
timing), or a state change that no valid, accepted message explains.
"""
from __future__ import annotations

import math
import socket
import time
import traceback
from pathlib import Path

from pymavlink.dialects.v20 import common as mavlink2
from mavreg.config.paths import PARAMS_DIR
from .frames import pack

__all__ = ["DaemonTarget", "VehicleTarget", "STALL_S"]

STALL_S = 1.0
"""An input that takes longer than this is reported as a stall (the paths take microseconds)."""
_REPO = Path(__file__).resolve().parents[1]
_VEHICLE_ADDR = ("127.0.0.1", 14540)
_RATES = ("rollspeed", "pitchspeed", "yawspeed")
_USED = {"ATTITUDE_QUATERNION": ("q1", "q2", "q3", "q4") + _RATES, "ATTITUDE": ("roll", "pitch", "yaw") + _RATES,
         "LOCAL_POSITION_NED": ("x", "y", "z", "vx", "vy", "vz")}
"""The fields of each state part the daemon uses."""


def _finding(kind: str, data: bytes, detail: str) -> str:
    return f"{kind}: {detail} (input {len(data)} bytes: {data[:64].hex()}{'...' if len(data) > 64 else ''})"



def _receive(receive, data: bytes) -> tuple[bool, list[str]]:
    """Run one receive path on ``data``: (whether it raised, findings): an exception that
    escaped, or a stall beyond :data:`STALL_S`."""
    t0 = time.perf_counter()
    try:
        receive()
    except Exception:
        return True, [_finding("exception", data, traceback.format_exc(limit=3).strip().splitlines()[-1])]
    elapsed = time.perf_counter() - t0
    return False, ([_finding("stall", data, f"{elapsed:.2f} s")] if elapsed > STALL_S else [])

class DaemonTarget:
    """The daemon's receive path (see the module docstring); ``impl``: ``fast`` or ``reference``."""

    def __init__(self, impl: str = "fast"):
        from mavreg.config.vehicle import load_vehicle
        from mavreg.daemon.vehicle.link import FastLink
        from mavreg.daemon.vehicle.link_reference import MavlinkLink
        from mavreg.daemon.flight.supervisor import Supervisor, SupervisorParams
        self.sup = Supervisor(load_vehicle(PARAMS_DIR / "vehicles/mk_quadro.yaml"), SupervisorParams(),
                              lambda plan: None)
        self.passed: list = []
        if impl == "fast":
            self.link = FastLink("udpout", _VEHICLE_ADDR, 1, 1, self._on_message, None, sock=None)
        else:
            self.link = MavlinkLink("udpout", _VEHICLE_ADDR, 1, 1, self._on_message)
        self.frames = 0
        self._now = 0.0

    def _on_message(self, msg, t_ns: int) -> None:
        self.passed.append(msg)
        self._now += 0.002
        self.sup.handle(msg, self._now)

    def snapshot(self) -> tuple:
        s, st = self.sup, self.sup.vehicle_status
        return (None if st is None else (st.armed, st.mode), s.phase,
                None if s.last_sample is None else s.last_sample.time_boot_ms,
                tuple(sorted(s.assembler._att)), tuple(sorted(s.assembler._pos)), s.counters.acks,
                s.timesync.estimate())

    def _non_finite_parts(self, quat_seen: bool) -> int:
        """State parts from the vehicle among the messages passed on whose used fields are not
        all finite, or quaternions too far from unit norm to normalize (each must be dropped
        and counted by the state assembler)."""
        n = 0
        p = self.sup.params
        for m in self.passed:
            kind = m.get_type()
            if (m.get_srcSystem(), m.get_srcComponent()) != (p.vehicle_system_id, p.vehicle_component_id):
                continue
            quat_seen_now, quat_seen = quat_seen, quat_seen or kind == "ATTITUDE_QUATERNION"
            if kind == "ATTITUDE" and quat_seen_now:
                continue                                   # ignored once quaternions come
            fields = _USED.get(kind, ())
            if fields and not all(math.isfinite(getattr(m, f)) for f in fields):
                n += 1
            elif kind == "ATTITUDE_QUATERNION" and math.sqrt(m.q1 ** 2 + m.q2 ** 2 + m.q3 ** 2 + m.q4 ** 2) < 0.5:
                n += 1                                     # no rotation: refused with them
        return n

    def feed(self, data: bytes) -> list[str]:
        before = self.snapshot()
        non_finite0 = self.sup.assembler.counters.non_finite
        quat_seen = self.sup.assembler.quaternion_seen
        self.passed = []
        raised, out = _receive(lambda: self.link.datagram_received(data, _VEHICLE_ADDR), data)
        self.frames += 1
        if raised:
            return out
        after = self.snapshot()
        if after != before and not any(m.get_type() != "BAD_DATA" for m in self.passed):
            out.append(_finding("state_change", data, f"without a valid message: {before} -> {after}"))
        sample = self.sup.last_sample
        if sample is not None and after[2] != before[2]:
            if not all(math.isfinite(v) for v in sample.x.tolist()):
                out.append(_finding("non_finite_state", data, f"sample {sample.x.tolist()}"))
        expected = self._non_finite_parts(quat_seen)
        got = self.sup.assembler.counters.non_finite - non_finite0
        if got != expected:
            out.append(_finding("non_finite_count", data, f"{expected} non-finite state parts, {got} counted"))
        return out


class VehicleTarget:
    """firmware_sim's receive path through its UDP socket (see the module docstring)."""

    def __init__(self, system_id: int = 1, component_id: int = 191):
        from firmware_sim.autopilot import OFFBOARD_TARGETS
        from firmware_sim.cli import build_engine, build_parser
        self.offboard_targets = OFFBOARD_TARGETS     # rotor forces or body rates: they name the peer
        args = build_parser().parse_args(["--listen", "udpin:127.0.0.1:0", "--world", "ideal", "--quiet"])
        self.engine, _ = build_engine(args)
        self.ap = self.engine.ap
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.setblocking(False)
        self.addr = (self.engine.link.host, self.engine.link.port)
        self.parser = mavlink2.MAVLink(None)
        self.parser.robust_parsing = True
        self.frames = 0
        self._introduce(system_id, component_id)

    def _introduce(self, system_id: int, component_id: int) -> None:
        """A HEARTBEAT from the configured peer, as the daemon sends first: the vehicle learns
        its address (:mod:`firmware_sim.peers`), so that fuzzed frames from it reach the autopilot."""
        hb = mavlink2.MAVLink_heartbeat_message(mavlink2.MAV_TYPE_ONBOARD_CONTROLLER,
                                                mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)
        self.sock.sendto(pack(hb, system_id, component_id), self.addr)
        if self.engine.link.wait_readable(1.0):
            while self.engine.process_datagram():
                pass

    def close(self) -> None:
        self.sock.close()
        self.engine.link.close()

    def snapshot(self) -> tuple:
        ap = self.ap
        return (ap.armed, ap.mode, ap.failsafe, ap.offboard_component, ap.target_n, ap.target_count)

    def _decode(self, data: bytes) -> list:
        p = mavlink2.MAVLink(None)
        p.robust_parsing = True
        try:
            return [m for m in (p.parse_buffer(data) or []) if m.get_type() != "BAD_DATA"]
        except Exception:
            return []

    def _replies(self) -> list:
        out = []
        while True:
            try:
                data = self.sock.recv(65535)
            except (BlockingIOError, InterruptedError):
                return out
            try:
                out += [m for m in (self.parser.parse_buffer(data) or []) if m.get_type() != "BAD_DATA"]
            except Exception:
                pass

    def feed(self, data: bytes) -> list[str]:
        ap = self.ap
        before = self.snapshot()
        valid_targets = [m for m in self._decode(data) if m.get_type() in self.offboard_targets
                         and ap.target_drop_reason(m) is None]
        self.sock.sendto(data, self.addr)
        def receive():
            # loopback delivers at once; wait only if the datagram is not there yet
            if self.engine.process_datagram() or (self.engine.link.wait_readable(STALL_S)
                                                  and self.engine.process_datagram()):
                while self.engine.process_datagram():
                    pass
        raised, out = _receive(receive, data)
        self.frames += 1
        if raised:
            return out
        after = self.snapshot()
        accepted = {m.command for m in self._replies()
                    if m.get_type() == "COMMAND_ACK" and m.result == mavlink2.MAV_RESULT_ACCEPTED}
        if after[:3] != before[:3] and not accepted & {mavlink2.MAV_CMD_COMPONENT_ARM_DISARM,
                                                       mavlink2.MAV_CMD_DO_SET_MODE,
                                                       mavlink2.MAV_CMD_NAV_TAKEOFF,
                                                       mavlink2.MAV_CMD_NAV_LAND}:
            out.append(_finding("state_change", data, f"armed/mode without an accepted command: {before} -> {after}"))
        if after[3:] != before[3:] and not valid_targets:
            out.append(_finding("state_change", data, f"offboard peer/target without a valid target: "
                                f"{before[3:]} -> {after[3:]}"))
        fmax = ap.cfg.max_rotor_thrust_n
        if not all(math.isfinite(f) and 0.0 <= f <= fmax for f in ap.target_n):
            out.append(_finding("bad_target", data, f"target {ap.target_n}"))
        rates = list(ap.rates.queued) + ([ap.rates.setpoint] if ap.rates.setpoint else [])
        if not all(math.isfinite(x) for sp in rates for x in sp) or any(not 0.0 <= sp[3] <= 1.0 for sp in rates):
            out.append(_finding("bad_target", data, f"rate set-points {rates}"))
        return out
