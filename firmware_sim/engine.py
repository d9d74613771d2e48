"""Glue between the link, the autopilot and the simulation, one control period at a time.

The clocks in :mod:`firmware_sim.clock` decide *when* these run.
"""
from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink2

from . import modes
from .autopilot import Autopilot
from .link import Link
from .sim import Simulation

__all__ = ["Engine"]


class Engine:
    """One emulator instance: simulation + autopilot + link.

    Parameters
    ----------
    sim : Simulation
    autopilot : Autopilot
    link : Link
    """

    def __init__(self, sim: Simulation, autopilot: Autopilot, link: Link):
        self.sim = sim
        self.ap = autopilot
        self.link = link
        self.counters = {"lockstep_timeouts": 0, "overruns": 0}

    def process_datagram(self) -> bool:
        """Handle one waiting datagram; ``False`` when none was waiting."""
        got = self.link.recv_datagram()
        if got is None:
            return False
        msgs, _ = got
        sim = self.sim
        for msg in msgs:
            out = self.ap.handle(msg, sim.t_s, sim.state, sim.on_ground)
            if out:
                self.link.send(out)
        return True

    def poll(self) -> None:
        """Handle every waiting datagram."""
        while self.process_datagram():
            pass

    def begin_period(self) -> None:
        """Autopilot timeouts and heartbeat, then the telemetry of the current state."""
        sim = self.sim
        out = self.ap.update(sim.t_s, sim.state, sim.on_ground)
        out.extend(self.ap.telemetry(sim.t_s, sim.state))
        self.link.send(out)

    def step(self) -> None:
        """Advance the physics one control period with the autopilot's rotor command."""
        sim, ap = self.sim, self.ap
        cmd = ap.rotor_command_n(sim.state, sim.on_ground)
        sim.advance(cmd, ap.armed, ap.mode)

    def announce_stop(self, reason: str) -> None:
        """Tell the peers why the simulation stopped (STATUSTEXT, critical)."""
        self.link.send([mavlink2.MAVLink_statustext_message(
            mavlink2.MAV_SEVERITY_CRITICAL, f"sim stopped: {reason}".encode()[:50], 0, 0)])

    def status_line(self) -> str:
        """One line: time, mode, armed, position, speed, drops, counters."""
        s = self.sim.state
        speed = math.sqrt(s[7] ** 2 + s[8] ** 2 + s[9] ** 2)
        drops = " ".join(f"{k}={v}" for k, v in self.ap.drops.items() if v) or "none"
        extra = " ".join(f"{k}={v}" for k, v in self.counters.items() if v)
        return (f"t={self.sim.t_s:9.3f}s {modes.MODE_NAMES.get(self.ap.mode, '?'):8s} "
                f"{'ARMED   ' if self.ap.armed else 'disarmed'} "
                f"ned=({s[0]:7.2f},{s[1]:7.2f},{s[2]:7.2f})m speed={speed:5.2f}m/s "
                f"{'ground ' if self.sim.on_ground else ''}peers={len(self.link.peers)} "
                f"drops: {drops}{(' ' + extra) if extra else ''}")
