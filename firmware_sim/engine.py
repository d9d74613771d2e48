"""Glue between the link, the world, the autopilot and the simulation, one control period at a time.

The clocks in :mod:`firmware_sim.clock` decide *when* these run. The world
(:mod:`firmware_sim.world`) sits between the autopilot and the socket: received
datagrams go through the uplink delay line (:class:`firmware_sim.channel.Uplink`) and
are handled when due, at physics-step granularity, also in the middle of a control
period; everything the vehicle sends goes through the downlink delay line
(:class:`firmware_sim.channel.Downlink`), released at period boundaries; the telemetry
describes the estimate (:class:`firmware_sim.estimator.Estimator`) when the world has
one. The autopilot's own HOLD/LAND stabilizer flies on the true state; its rate loop (rate
set-points, :mod:`firmware_sim.rate_loop`) on the body rates published last, the estimate's.
"""
from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mavlink2

from . import modes
from .autopilot import OFFBOARD_TARGETS, Autopilot, state_messages
from .channel import Downlink, Uplink
from .estimator import Estimator
from .faults import FaultyDownlink, FaultyUplink
from .link import Link
from .px4 import STATE_IDS, Px4Services
from .reboot import Reboots, fresh_autopilot
from .sim import Simulation
from .world import PRESETS, WorldPreset

__all__ = ["Engine"]

_UNDELAYED = ("HEARTBEAT", "BAD_DATA")
_IDLE = (0.0, 0.0, 0.0, 0.0)


class Engine:
    """One emulator instance: simulation + autopilot + link + world.

    Parameters
    ----------
    sim : Simulation
    autopilot : Autopilot
    link : Link
    world : WorldPreset, optional
        Default: the ideal world.
    link_faults : firmware_sim.faults.LinkFaults, optional
        Faults after the world's link model, in simulation time (``--link-faults``).
    reboots : Reboots, optional
        The autopilot's reboots (:mod:`firmware_sim.reboot`); default: by command only, 1.5 s.
    log : callable, optional
        ``log(line)``: what happens to the autopilot (its reboots), as it happens.

    Attributes
    ----------
    targets_received : int
        Valid offboard targets (SET_ACTUATOR_CONTROL_TARGET or SET_ATTITUDE_TARGET) received
        (counted on arrival, before the uplink's delay and loss): what the lockstep loop waits for.
    gyro_rad_s : tuple or None
        The body rates published last (the estimate's): what the autopilot's rate loop flies on.
    complete_released : int
        Complete state bundles the last :meth:`begin_period` released to the peers.
    boot_t_s : float
        Sim time of the autopilot's last boot: its clock (``time_boot_ms``, TIMESYNC, its
        timeouts) is sim time less this.
    """

    def __init__(self, sim: Simulation, autopilot: Autopilot, link: Link,
                 world: WorldPreset | None = None, link_faults=None, reboots: Reboots | None = None,
                 log=None):
        self.sim = sim
        self.ap = autopilot
        if autopilot.px4.rate_hz != sim.params.rate_hz:     # the streams count control periods
            autopilot.px4 = Px4Services(autopilot.px4.cfg, sim.params.rate_hz)
            autopilot.rates.set_rate_hz(sim.params.rate_hz)
        self._status: list = []
        self.link = link
        self.world = world if world is not None else PRESETS["ideal"]
        p = sim.params
        self._physics_hz = p.physics_hz
        self._substeps = p.substeps
        self.downlink = Downlink(self.world.link, p.rate_hz, p.substeps, p.seed)
        self.uplink = Uplink(self.world.link, p.physics_hz, p.seed)
        if link_faults is not None:
            self.downlink = FaultyDownlink(self.downlink, link_faults.down, p.rate_hz)
            self.uplink = FaultyUplink(self.uplink, link_faults.up, p.physics_hz)
        # ideal link: send at once, skip the delay lines
        self._direct = self.world.link.ideal and link_faults is None
        est = self.world.estimator
        latency_steps = int(math.floor(est.latency_s * p.physics_hz + 0.5))
        self.estimator = Estimator(est, 1.0 / p.rate_hz, p.seed) if est.has_errors else None
        self.estimating = self.estimator is not None or latency_steps > 0
        if latency_steps > 0:
            sim.keep_history(latency_steps)
        self.counters = {"lockstep_timeouts": 0, "overruns": 0, "dropped_rebooting": 0}
        self.reboots = reboots if reboots is not None else Reboots()
        self.boot_t_s = 0.0
        self.log = log
        self.targets_received = 0
        self.complete_released = 0
        self.gyro_rad_s = None

    # ---------------------------------------------------------------- uplink
    def process_datagram(self) -> bool:
        """Read and take one waiting datagram; ``False`` when none was waiting."""
        got = self.link.recv_datagram()
        if got is None:
            return False
        self.receive(got[0])
        return True

    def poll(self) -> None:
        """Take every waiting datagram."""
        while self.process_datagram():
            pass

    def receive(self, msgs) -> None:
        """Take the decoded messages of one datagram received now (sim time ``sim.t_s``)."""
        step = self.sim.step_count
        ap = self.ap
        if self.reboots.down:                # nobody listens: lost (targets still pace lockstep)
            self.counters["dropped_rebooting"] += len(msgs)
            self.targets_received += sum(1 for m in msgs if m.get_type() in OFFBOARD_TARGETS)
            return
        if self.uplink.ideal:                # handled now: the autopilot counts valid targets
            n0 = ap.target_count
            self._handle(msgs, step)
            self.targets_received += ap.target_count - n0
            self._send_due()
            return
        carries_target = False
        undelayed = True
        for m in msgs:
            mtype = m.get_type()
            if mtype in OFFBOARD_TARGETS:
                carries_target = True
                if ap.target_drop_reason(m) is None:
                    self.targets_received += 1
            if mtype not in _UNDELAYED:
                undelayed = False
        if undelayed:
            self._handle(msgs, step)
        elif self.uplink.push(step, msgs, carries_target):
            for due in self.uplink.pop_due(step):
                self._handle(due, step)
        self._send_due()

    def _handle(self, msgs, step: int) -> None:
        """The autopilot handles ``msgs`` at physics step ``step``; replies go down the link."""
        sim, ap = self.sim, self.ap
        if self.reboots.down:
            self.counters["dropped_rebooting"] += len(msgs)
            return
        t = step / self._physics_hz
        tb = t - self.boot_t_s
        for msg in msgs:
            out = ap.handle(msg, tb, sim.state, sim.on_ground)
            if ap.reboot_requested:
                ap.reboot_requested = False
                self.reboots.request(t)
            if out:
                if self._direct:
                    self.downlink.sent += len(out)
                    self.link.send(out)
                else:
                    self.downlink.push_reply(step, out)

    def _send_due(self) -> int:
        """Send what the downlink releases now; return the complete state bundles among it."""
        if self._direct:
            return 0
        msgs, complete = self.downlink.release(self.sim.step_count // self._substeps)
        if msgs:
            self.link.send(msgs)
        return complete

    # ---------------------------------------------------------------- period
    def begin_period(self) -> None:
        """Commands due now, autopilot timeouts and heartbeat, then the telemetry of this period."""
        sim = self.sim
        step = sim.step_count
        if self.uplink.next_due() is not None:
            for due in self.uplink.pop_due(step):
                self._handle(due, step)
        t = sim.t_s
        self._reboot_step(t)
        if self.reboots.down:                # silent; what was already on the wire still arrives
            self.complete_released = 0 if self._direct else self._send_due()
            return
        out = self.ap.update(t - self.boot_t_s, sim.state, sim.on_ground)
        state = self._state_messages(t, step // self._substeps)
        out.extend(self._status)
        if self._direct:
            out.extend(m for m in state if m is not None)
            self.downlink.sent += len(out)
            self.link.send(out)
            self.complete_released = int(state[1] is not None and state[2] is not None and bool(self.link.peers))
            return
        self.downlink.push_period(step // self._substeps, out, state)
        released = self._send_due()                  # due messages leave (to nobody, when none is known)
        self.complete_released = released if self.link.peers else 0       # nobody to answer them

    def _state_messages(self, t: float, period: int) -> tuple:
        """The state messages of period ``period`` (``None`` for one whose stream is not due
        then, :mod:`firmware_sim.px4`); the status messages due go to ``self._status``."""
        sim = self.sim
        if self.estimating:
            s = sim.lagged_state
            if self.estimator is not None:
                pos, vel, q, rates = self.estimator.publish(s)
            else:
                pos, vel, q, rates = s[0:3], s[7:10], s[3:7], s[10:13]
        else:
            s = sim.state
            pos, vel, q, rates = s[0:3], s[7:10], s[3:7], s[10:13]
        self.gyro_rad_s = rates
        rec = sim.recorder
        if rec is not None:
            rec.record_estimate(t, pos, vel, q, rates)
        px4, tb = self.ap.px4, t - self.boot_t_s
        self._status = px4.periodic(period, tb, pos, vel, q, rates, self.ap, sim.on_ground, sim.applied_n)
        return tuple(m if px4.due(i, period) else None
                     for i, m in zip(STATE_IDS, state_messages(tb, pos, vel, q, rates)))

    def step(self) -> None:
        """Advance the physics one control period with the autopilot's rotor command.

        Commands that fall due inside the period are handled at their physics step, and
        the rotor command is taken again from the autopilot from there on.
        """
        sim, ap, up = self.sim, self.ap, self.uplink
        end = sim.step_count + self._substeps
        down = self.reboots.down          # no command, recorded as mode 0
        armed, mode = ap.armed and not down, 0 if down else ap.mode
        while True:
            cmd = _IDLE if down else ap.rotor_command_n(sim.state, sim.on_ground, sim.t_s - self.boot_t_s,
                                                         self.gyro_rad_s)
            due = up.next_due()
            if due is None or due >= end:
                sim.advance(cmd, armed, mode, end - sim.step_count)
                return
            if due > sim.step_count:
                sim.advance(cmd, armed, mode, due - sim.step_count)
            step = sim.step_count
            for msgs in up.pop_due(step):
                self._handle(msgs, step)

    # ---------------------------------------------------------------- reboots
    def _reboot_step(self, t: float) -> None:
        """The autopilot goes down or comes back at ``t`` when due (:mod:`firmware_sim.reboot`)."""
        due = self.reboots.due(t)
        if due == "down":
            rec, sim = self.reboots.records[-1], self.sim
            rec.armed, rec.on_ground = self.ap.armed, sim.on_ground
            sim.ground.survive_impact = not sim.on_ground      # its fall is the fault's, not a crash exit
            self.ap = fresh_autopilot(self.ap)                  # disarmed: the rotors get nothing
            link_filter = getattr(self.link, "filter", None)
            if link_filter is not None:
                link_filter.forget()
            self._say(f"autopilot down at t={t:.3f} s ({rec.why})" + (
                "; armed in the air: the motors stop, the vehicle falls" if rec.armed and not rec.on_ground else ""))
        elif due == "up":
            while (got := self.link.recv_datagram()) is not None:    # sent while it was down: lost
                self.counters["dropped_rebooting"] += len(got[0])
            self.boot_t_s = t
            if self.estimator is not None:
                p = self.sim.params
                self.estimator = Estimator(self.world.estimator, 1.0 / p.rate_hz, p.seed)
            self._say(f"autopilot up again at t={t:.3f} s: time_boot_ms from 0, disarmed, HOLD")

    def _say(self, line: str) -> None:
        if self.log is not None:
            self.log(line)

    def run_meta(self) -> dict:
        """The run's drop counters, counters, reboots and the impacts of falls they caused."""
        return {"drops": self.drops(), "counters": self.all_counters(),
                "reboots": [r.as_dict() for r in self.reboots.records], "reboot_impacts": self.sim.ground.impacts}

    # ---------------------------------------------------------------- reporting
    def drops(self) -> dict:
        """Every drop counter: the autopilot's and the link's (signing, peers), summed by reason."""
        out = dict(self.ap.drops)
        link_filter = getattr(self.link, "filter", None)
        for k, v in (link_filter.drops if link_filter is not None else {}).items():
            out[k] = out.get(k, 0) + v
        return out

    def all_counters(self) -> dict:
        """Loop counters and link statistics."""
        return {**self.counters, "telemetry_sent": self.downlink.sent, "telemetry_lost": self.downlink.lost,
                "commands_received": self.uplink.received, "commands_lost": self.uplink.lost,
                "targets_received": self.targets_received}

    def announce_stop(self, reason: str) -> None:
        """Tell the peers why the simulation stopped (STATUSTEXT, critical; not delayed)."""
        self.link.send([mavlink2.MAVLink_statustext_message(
            mavlink2.MAV_SEVERITY_CRITICAL, f"sim stopped: {reason}".encode()[:50], 0, 0)])

    def status_line(self) -> str:
        """One line: time, mode, armed, position, speed, drops, counters."""
        s = self.sim.state
        speed = math.sqrt(s[7] ** 2 + s[8] ** 2 + s[9] ** 2)
        drops = " ".join(f"{k}={v}" for k, v in self.drops().items() if v) or "none"
        counters = {**self.counters, "telemetry_lost": self.downlink.lost, "commands_lost": self.uplink.lost}
        extra = " ".join(f"{k}={v}" for k, v in counters.items() if v)
        return (f"t={self.sim.t_s:9.3f}s {modes.MODE_NAMES.get(self.ap.mode, '?'):8s} "
                f"{'ARMED   ' if self.ap.armed else 'disarmed'} "
                f"ned=({s[0]:7.2f},{s[1]:7.2f},{s[2]:7.2f})m speed={speed:5.2f}m/s "
                f"{'ground ' if self.sim.on_ground else ''}peers={len(self.link.peers)} "
                f"drops: {drops}{(' ' + extra) if extra else ''}")
