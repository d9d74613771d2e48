"""The daemon's side of the vehicle link: each read of the link handled, what the supervisor
says sent, logged and stamped, and a telemetry gap filled from the prediction.

Mixed into :class:`~mavreg.daemon.jobs.app.Daemon` (its attributes: ``config``, ``supervisor``,
``link``, ``gcs``, ``ctrl_log``, ``log``, ``clock_s``, ``latency_ns``, ...). The link hands on
every message of a read (:meth:`VehicleIO._on_message`) and says when the read is done
(:meth:`VehicleIO._on_read_end`): the messages are then handled together, and of the complete
samples among them only the newest is answered (:meth:`Supervisor.handle_many
<mavreg.daemon.flight.supervisor.Supervisor.handle_many>`), so a loop that fell behind its telemetry
acts once on the vehicle's state now instead of on a backlog of states it has left.
"""
from __future__ import annotations

import asyncio
import dataclasses
import time

from ..flight.phases import Output, Phase

__all__ = ["VehicleIO"]


class VehicleIO:
    """The vehicle link's part of the daemon (a mixin of :class:`~mavreg.daemon.jobs.app.Daemon`)."""

    def _emit(self, out: Output) -> bool:
        sent_actuator = False
        if out.messages and self.link is not None and self.link.send_many(out.messages):
            sent_actuator = any(m.get_type() == "SET_ACTUATOR_CONTROL_TARGET" for m in out.messages)
        if out.events or self.ctrl_log.clock_anchor is None:
            self._stamp_events(out)
        for ev in out.events:
            self.ctrl_log.events.append(ev)
            self.log(ev.line())
        if out.log is not None and self.config.keep_control_log:
            self.ctrl_log.append(out.log)
        if self.gcs is not None:
            self.gcs.daemon_output(out)
        if self.supervisor.finished and not self._flight_closed:
            self._close_flight()
        return sent_actuator

    def _stamp_events(self, out: Output) -> None:
        """Give the events the daemon's clock; note both clocks at the vehicle's first sample
        (the control log counts earlier events back from there on the vehicle's axis)."""
        daemon_s = self.clock_s() - self._start_s
        out.events[:] = [dataclasses.replace(ev, daemon_s=daemon_s) for ev in out.events]
        if self.ctrl_log.clock_anchor is None and self.supervisor.last_sample is not None:
            self.ctrl_log.clock_anchor = (daemon_s, self.supervisor.last_sample.time_s)

    def _on_message(self, msg, t_recv_ns: int) -> None:
        """The link's callback for each message read: kept until the read is done; a lockstep
        vehicle's at once (it waits for each answer, and the .tlog keeps each command right
        after its sample, as ``mavreg identify`` pairs them)."""
        if self.config.supervisor.lockstep:
            self._handle_read([msg], t_recv_ns)
            return
        if not self._inbox:
            self._inbox_t_ns = t_recv_ns
        self._inbox.append(msg)

    def _on_read_end(self) -> None:
        """The link's callback once a read is done (every datagram that was waiting, or a
        chunk of a serial or TCP stream): its messages are handled together, and of the
        samples among them only the newest is answered (:meth:`Supervisor.handle_many`)."""
        if self._inbox:
            msgs, self._inbox = self._inbox, []
            self._handle_read(msgs, self._inbox_t_ns)

    def _handle_read(self, msgs: list, t_recv_ns: int) -> None:
        self._heard = True
        if not self._greeted:
            # on udpin: nothing could be sent before the vehicle was heard; our HEARTBEAT goes
            # first, so a vehicle that takes commands only from a known peer (the emulator)
            # knows us before the first command instead of up to a heartbeat period later
            self._greeted = self.link is not None and self.link.send(self.supervisor.heartbeat())
        for msg in msgs:
            if msg.get_type() == "HEARTBEAT":
                self._last_heartbeat = msg      # a new flight's supervisor starts from it
        sent, rest = False, msgs
        while rest:                     # a flight that ends mid-read hands the rest to the next
            out = self.supervisor.handle_many(rest, self.clock_s())
            sent = self._emit(out) or sent
            rest = rest[len(rest) if out.taken is None else out.taken:]
        if sent:
            dt = time.perf_counter_ns() - t_recv_ns
            self.latency_ns.append(dt)
            if self.supervisor.phase == Phase.MANEUVER:
                self.maneuver_latency_ns.append(dt)
            self._arm_gap_timer(1.5)
        if self.gcs is not None:            # after the command: a ground station never delays it
            for msg in msgs:
                self.gcs.vehicle_message(msg)

    def _arm_gap_timer(self, periods: float) -> None:
        """(Re)start the timer that fills a telemetry gap (real time only)."""
        if not self.config.supervisor.gap_fill:
            return
        if self._gap_timer is not None:
            self._gap_timer.cancel()
        loop = asyncio.get_running_loop()
        self._gap_timer = loop.call_later(periods * self.supervisor.forecaster.period_s, self._fill_gap)

    def _fill_gap(self) -> None:
        self._gap_timer = None
        if self._emit(self.supervisor.fill_gap(self.clock_s())):
            self._arm_gap_timer(1.0)
