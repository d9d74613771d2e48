"""The messages in, one by one, to the part each one is for (sans-I/O; a part of the
:class:`~mavreg.daemon.flight.supervisor.Supervisor`).

:meth:`Inbox.take` checks a message is the vehicle's (its ids), shows a state part to the
reboot detector, and routes it: a HEARTBEAT (the dialect, then the vehicle's status and what a
change of it does to the flight), PARAM_VALUE to the autopilot's checks, COMMAND_ACK, the landed
state, TIMESYNC; the state parts to the sample assembler, whose complete sample it returns for
the supervisor's per-sample pipeline.
"""
from __future__ import annotations

import math

from ..vehicle import messages as mm
from .phases import AIRBORNE, Output, Phase
from .reboot import STATE_PARTS, on_reboot
from .safety import SafetyPolicy
from .state import StateSample
from .verbs import Flight

__all__ = ["Inbox"]


class Inbox:
    """The messages of one flight in (see the module docstring).

    Parameters
    ----------
    flight : Flight
    safety : SafetyPolicy
    """

    def __init__(self, flight: Flight, safety: SafetyPolicy):
        self.flight = flight
        self.safety = safety

    def take(self, msg, now_s: float, out: Output) -> StateSample | None:
        """One message: routed; the complete sample it closes, if any (not yet acted on)."""
        parts = self.flight.parts
        mtype = msg.get_type()
        if not self._vehicle_ids(msg, mtype, out):
            parts.counters.foreign_dropped += 1
            return None
        if mtype in STATE_PARTS and (seen := parts.reboots.part(msg, now_s)) is not None:
            on_reboot(self.flight, self.safety, seen, out)
        if mtype == "HEARTBEAT":
            self._heartbeat(msg, out)
        elif mtype == "PARAM_VALUE":
            parts.autopilot.param_value(msg)
        elif mtype == "COMMAND_ACK":
            self._on_ack(msg, out)
        elif mtype == "EXTENDED_SYS_STATE":
            self.flight.ctx.heard.landed_state = int(msg.landed_state)
        elif mtype == "TIMESYNC":
            if msg.tc1 != 0 and not parts.timesync.reply(msg.tc1, msg.ts1, int(now_s * 1e9)):
                parts.counters.timesync_dropped += 1
        else:
            sample = parts.assembler.add(msg)
            if sample is not None:
                parts.counters.samples += 1
                return sample
        return None

    def _vehicle_ids(self, msg, mtype: str, out: Output) -> bool:
        """Whether ``msg`` is the vehicle's (:class:`~mavreg.daemon.vehicle.peers.VehicleIds`: its system
        id pinned, or fixed by its first autopilot HEARTBEAT, which is announced)."""
        ids = self.flight.parts.ids
        known = ids.system_id is not None
        hb = (int(msg.type), int(msg.autopilot)) if mtype == "HEARTBEAT" else None
        if not ids.take(msg.get_srcSystem(), msg.get_srcComponent(), hb):
            return False
        if not known:
            self.flight.event(out, "vehicle_id", f"vehicle system id {ids.system_id}, from its first autopilot "
                              f"HEARTBEAT (autopilot {hb[1]}); pin another with --vehicle-system-id N")
        return True

    def _heartbeat(self, msg, out: Output) -> None:
        """A vehicle HEARTBEAT: the dialect (its notice), then the vehicle's status; a vehicle
        mavreg does not fly is refused on the ground at once."""
        parts, ctx = self.flight.parts, self.flight.ctx
        autopilot = parts.autopilot
        parts.reboots.heartbeat(ctx.now_wall_s)
        # the telemetry is asked for until samples stream: from the start, and on the ground when
        # they stopped (a rebooted ArduCopter sends none until asked again)
        last_wall_s = ctx.heard.last_sample_wall_s
        streaming = last_wall_s is not None and (
            ctx.phase in AIRBORNE or ctx.now_wall_s - last_wall_s <= parts.params.stale_timeout_s)
        st = autopilot.heartbeat(msg, out.messages, streaming)
        if autopilot.notice is not None:
            self.flight.announce(out, "dialect", mm.SEVERITY_WARNING, autopilot.notice)
            autopilot.notice = None
        if st is not None:
            self._on_heartbeat(st, out)
            return
        parts.counters.unsupported_heartbeats += 1
        if ctx.phase == Phase.PREFLIGHT:
            self.safety.refuse(autopilot.refusal, out, Phase.PREFLIGHT)

    def _on_heartbeat(self, st: mm.VehicleStatus, out: Output) -> None:
        flight, ctx = self.flight, self.flight.ctx
        prev = ctx.heard.status
        ctx.heard.status = st
        if prev is None or prev.armed != st.armed or prev.mode != st.mode:
            flight.event(out, "vehicle", f"vehicle {'armed' if st.armed else 'disarmed'}, mode {st.mode}")
        if ctx.phase == Phase.TERMINATE:
            if not st.armed:
                self.safety.disarm_confirmed(out, "the vehicle reports disarmed")
        elif ctx.phase == Phase.LAND and ctx.landing.spool_down_start_vehicle_s is not None and not st.armed:
            flight.set_phase(out, Phase.DISARMED, "touched down and disarmed")
        elif ctx.phase == Phase.PREFLIGHT and ctx.landing.requested and not st.armed:
            flight.set_phase(out, Phase.DISARMED, "disarmed on the ground")
        elif (ctx.phase == Phase.LAND and ctx.landing.mode_requested
              and st.mode == flight.parts.autopilot.dialect.land_mode):
            pass                           # on the ground, the autopilot's landing mode disarms
        elif ctx.phase in AIRBORNE and (not st.armed or not st.offboard):
            self.safety.hand_over(out, "vehicle_mode", math.nan, math.nan, "",
                                  f"vehicle left OFFBOARD control (armed={st.armed}, mode {st.mode}); "
                                  "its failsafe is in charge")

    def _on_ack(self, msg, out: Output) -> None:
        self.flight.parts.counters.acks += 1
        accepted = msg.result == mm.mavlink2.MAV_RESULT_ACCEPTED
        if not accepted:
            self.flight.event(out, "command_refused", f"command {msg.command} result {msg.result}")
        if (accepted and self.flight.ctx.phase == Phase.TERMINATE
                and msg.command == mm.mavlink2.MAV_CMD_COMPONENT_ARM_DISARM):
            self.safety.disarm_confirmed(out, "forced disarm acknowledged")
