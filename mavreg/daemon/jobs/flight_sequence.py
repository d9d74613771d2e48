"""The daemon's flights one after another: a fresh supervisor for each, its record, its logs.

Mixed into :class:`~mavreg.daemon.jobs.app.Daemon` (its attributes: ``config``, ``supervisor``,
``book``, ``link``, ``log``, ``ctrl_log``, ...). ``mavreg fly`` flies one flight
(``DaemonConfig.flights`` 1) and stops when it ends; ``mavreg serve`` begins the next flight
when one ends on the ground: at once after its own landing and disarm, and after a flight
that ended otherwise (aborted: the link lost, the vehicle taken from OFFBOARD) only once the
vehicle reports itself disarmed, so that a vehicle its pilot or its failsafe flies is never
taken back. The records and numbered log files are :mod:`mavreg.daemon.jobs.flight_book`'s.
"""
from __future__ import annotations

from typing import Callable

from ...control.estimation.forecast import Forecaster
from .ctrllog import ControlLog
from .flight_book import FlightRecord
from ..flight.phases import Phase
from ..flight.supervisor import Supervisor
from ..logs.outputs import write_or_say
from ..logs.tlog import TlogWriter, tlog_clock

__all__ = ["FlightSequence"]


class FlightSequence:
    """The flight-by-flight part of the daemon (a mixin of :class:`~mavreg.daemon.jobs.app.Daemon`)."""

    def _new_supervisor(self) -> Supervisor:
        """A supervisor for a new flight, with a forecaster of its own (nothing learned in one
        flight carries into the next but what the files say)."""
        config, ctl = self.config, self.config.controller
        forecaster = Forecaster(self.vehicle, 1.0 / config.control_rate_hz, predict=ctl.predict_delay,
                                max_horizon_s=ctl.max_prediction_s, disturbance=ctl.disturbance)
        return Supervisor(self.vehicle, config.supervisor, self.regulator_factory, envelope=config.envelope,
                          forecaster=forecaster, fixed_delay_s=ctl.fixed_delay_s)

    def _close_flight(self) -> None:
        """The flight has ended: its record, its logs; then the next flight, or the stop."""
        self._record_flight(stopped=False)
        if self.config.flights is not None and self.book.count >= self.config.flights:
            self._stop.set()
        elif self._signals:        # a signal in the air asked to land, then stop: not the next flight
            self.log("the daemon stops: a signal asked it to land, then stop")
            self._stop.set()
        elif self.supervisor.vehicle_refused:       # no later upload would fly: as fly does, stop
            self.log(f"the daemon stops: {self.supervisor.reason}")
            self._stop.set()
        elif self.supervisor.phase == Phase.DISARMED:
            self._next_flight()
        else:
            self._waiting_disarm = True
            self.log(f"the next flight begins once the vehicle reports itself disarmed (flight "
                     f"{self.flight_number} ended {self.supervisor.phase}: mavreg does not take a vehicle back "
                     "that its own failsafe or its pilot flies)")

    def _next_flight(self) -> None:
        """A fresh supervisor on the same link, endpoint and planner; a new numbered log."""
        self._waiting_disarm = False
        self.flight_number += 1
        previous = self.supervisor.reboots
        self.supervisor = self._new_supervisor()
        self.supervisor.reboots.carry_on(previous)      # the vehicle's clock outlives the flight
        self._flight_closed = False
        self.ctrl_log = ControlLog()
        self.plans.clear()
        self.latency_ns.clear()
        self.maneuver_latency_ns.clear()
        if self._tlog is not None:
            self._open_tlog()
        self.log(f"flight {self.flight_number}: waiting for an upload")
        if self._last_heartbeat is not None:    # the vehicle's status now, not at its next HEARTBEAT:
            self._emit(self.supervisor.handle(self._last_heartbeat, self.clock_s()))   # no sample unanswered

    def _save_control_log(self) -> None:
        if self._ctrl_files is None:
            return
        path = self._ctrl_files.begin(self.flight_number)
        write_or_say("control log", path, lambda: self.ctrl_log.save(path), self.log,
                     "the flight's outcome is in the status and on the log")

    def _open_tlog(self) -> None:
        """The current flight's ``.tlog`` (the previous one closed), handed to the link."""
        if self._tlog is not None:
            self._tlog.close()
        self._tlog = TlogWriter(self._tlog_files.begin(self.flight_number), self._tlog_clock(), self.log)
        if self.link is not None:
            self.link.tlog = self._tlog

    def _between_flights(self) -> None:
        """After a flight that did not end disarmed: the next once the vehicle is disarmed."""
        st = self.supervisor.vehicle_status
        if self._waiting_disarm and st is not None and not st.armed:
            self.log(f"the vehicle reports itself disarmed (mode {st.mode})")
            self._next_flight()

    def _no_flight_reason(self) -> str:
        sup = self.supervisor
        why = f"flight {self.flight_number} is over ({sup.phase}" + (f": {sup.reason})" if sup.reason else ")")
        if self._waiting_disarm:
            return why + "; the next flight begins once the vehicle reports itself disarmed"
        return why

    def _close_flight_on_stop(self) -> None:
        """A many-flight daemon stopped with a flight under way: its record and its log too."""
        if self.supervisor.phase == Phase.PREFLIGHT:
            self._flight_closed = True
            return                          # nothing took off: no flight to record
        self._record_flight(stopped=True)

    def _record_flight(self, stopped: bool) -> None:
        """The flight's record in the book (said, for a daemon of many flights), its control log."""
        self._flight_closed = True
        record = FlightRecord.of(self.flight_number, self.supervisor, self.latency_summary(),
                                 self.clock_s() - self._start_s, stopped=stopped)
        self.book.add(record)
        if self.config.flights != 1:
            self.log(record.line())
        self._save_control_log()

    def _tlog_clock(self) -> Callable[[], float]:
        """The ``.tlog``'s clock (:attr:`DaemonConfig.tlog_clock`, :func:`~.tlog.tlog_clock`) on
        the vehicle time of the flight under way."""
        def vehicle_s() -> float | None:
            sample = self.supervisor.last_sample
            return None if sample is None else sample.time_s

        return tlog_clock(self.config.tlog_clock, vehicle_s, self.wall_s)
