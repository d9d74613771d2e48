"""The asyncio daemon: wires the supervisor to the UDP link, the endpoint and the planner.

It owns every task it creates (heartbeat, tick, endpoint) and keeps their references;
:meth:`Daemon.run` returns when the flight is over or a stop is requested, then shuts
down in order: tasks cancelled and awaited, endpoint closed (socket removed), UDP closed,
``.tlog`` flushed, planner worker stopped. SIGINT/SIGTERM: the first asks the supervisor
to land (when airborne) and the second stops at once (the vehicle's failsafe then lands).
"""
from __future__ import annotations

import asyncio
import collections
import math
import signal
import time
from typing import Awaitable, Callable

from ...blas import one_blas_thread
from ...config.vehicle import VehicleParams
from ...errors import EXIT_FAILED, UserError
from ...planning.plan_io import text_in_cache
from ...progress import Progress, stderr_line
from .ctrllog import ControlLog
from .flight_book import FlightBook, NumberedFiles
from .flight_sequence import FlightSequence
from .vehicle_io import VehicleIO
from . import daemon_config
from .daemon_config import DaemonConfig, regulator_factory
from .status import latency_summary, status_report
from .endpoint import EndpointServer, jsonable
from ..gcs.link import GcsLink
from ..vehicle.link import FastLink, open_link
from ..vehicle.link_reference import MavlinkLink
from .planner_pool import PlannerDied, PlannerPool
from .sdnotify import Notifier
from .startup import PreflightWatch, compile_kernels, preflight_wait, warm_daemon_kernels
from ..flight.supervisor import Phase
from ..logs.tlog import TlogWriter

__all__ = ["DaemonConfig", "Daemon", "regulator_factory"]

TICK_S = 0.02
HEARTBEAT_S = 1.0


class Daemon(FlightSequence, VehicleIO):
    """One vehicle, one supervisor, optional control endpoint.

    ``signing`` (a :class:`mavreg.transport.signing.Signing`, or None): sign every frame sent
    and take only validly signed ones; its drop counters are in :meth:`status`.
    """

    def __init__(self, config: DaemonConfig, vehicle: VehicleParams, regulator_factory: Callable | None = None,
                 log: Callable[[str], None] | None = None, clock_s: Callable[[], float] = time.monotonic,
                 signing=None, progress: Progress | None = None, notifier: Notifier | None = None,
                 wall_s: Callable[[], float] = time.time):
        self.config = config
        self.wall_s = wall_s
        """The wall clock: read once, for the ``.tlog``'s first stamp; nothing that steers reads it."""
        self.signing = signing
        self.vehicle = vehicle
        self.clock_s = clock_s
        self.log = log if log is not None else stderr_line       # one write: stage lines come from threads
        self.progress = progress if progress is not None else Progress(self.log, clock_s)
        """The start's stage lines (:mod:`.startup`); its start is the daemon's (a command
        that printed before the daemon existed passes its own)."""
        self.notifier = notifier
        """systemd's (:mod:`.sdnotify`): READY=1 once the link is open and the endpoint
        listens, WATCHDOG=1 from the tick task (the loop itself), STOPPING=1 at the end."""
        self._watchdog_due_s = -math.inf
        self._start_s = self.progress.start_s
        """The injected clock when the daemon started: events carry the time since."""
        ctl = config.controller
        self.regulator_factory = regulator_factory if regulator_factory is not None else daemon_config.regulator_factory(
            vehicle, config.control_rate_hz, ctl.disturbance, ctl.allocation, ctl.speed_governor, warm=False)
        """(plan, rotor_lag) -> regulator; by default the controller file's at the config's control rate
        (its kernels are compiled as a stage of the start, :mod:`.startup`)."""
        self.supervisor = self._new_supervisor()
        self.book = FlightBook()
        """The outcomes of the flights flown (:mod:`.flight_book`)."""
        self.flight_number = 1
        """The flight under way (or the next one, between flights)."""
        self._flight_closed = False
        """The current supervisor's flight has ended and is in :attr:`book`."""
        self._waiting_disarm = False
        """Between flights after one that did not end disarmed: the next begins once the
        vehicle reports itself disarmed (a failsafe landed it, or its pilot flies it)."""
        many = config.flights != 1
        self._tlog_files = None if config.tlog_path is None else NumberedFiles(
            config.tlog_path, config.keep_logs, numbered=many)
        self._ctrl_files = None if config.control_log_path is None else NumberedFiles(
            config.control_log_path, config.keep_logs, numbered=many)
        self.ctrl_log = ControlLog()
        self.latency_ns: collections.deque = collections.deque(maxlen=200_000)
        self.maneuver_latency_ns: collections.deque = collections.deque(maxlen=200_000)
        self.uploads = {"accepted": 0, "rejected": 0}
        self.plans: list = []
        self.pool: PlannerPool | None = None
        self.link: FastLink | MavlinkLink | None = None
        self.endpoint: EndpointServer | None = None
        self.gcs: GcsLink | None = None
        self._tlog: TlogWriter | None = None
        self._tasks: list[asyncio.Task] = []
        self._stop = asyncio.Event()
        self._gap_timer: asyncio.TimerHandle | None = None
        self._signals = 0
        self._greeted = False
        """Our HEARTBEAT has answered the vehicle's first message (:meth:`_on_message`)."""
        self._heard = False
        self._last_heartbeat = None
        self._inbox: list = []
        """The messages of the read under way (:meth:`_on_message`, :meth:`_on_read_end`)."""
        self._inbox_t_ns = 0
        self._watch = PreflightWatch(self.progress.line)
        self.max_tick_gap_s, self.max_tick_gap_phase = 0.0, ""
        """Longest wall time between two runs of the tick task (the event loop's worst stall
        plus TICK_S, and the phase it was in): what a slow request or upload costs the loop."""
        self.max_tick_cpu_s = 0.0
        """Most CPU the loop's thread used between two ticks: the gap is this plus the time the
        process waited for a CPU (a loaded machine) or for events."""

    async def _heartbeat_task(self) -> None:
        while True:
            hb = self.supervisor.heartbeat()
            if self.link is not None:
                self.link.send(hb)
            if self.gcs is not None:
                self.gcs.heartbeat(hb, self.supervisor.phase)
            await asyncio.sleep(HEARTBEAT_S)

    async def _tick_task(self) -> None:
        last, last_cpu = time.perf_counter(), time.thread_time()
        while True:
            await asyncio.sleep(TICK_S)
            now, cpu = time.perf_counter(), time.thread_time()
            if now - last > self.max_tick_gap_s:
                self.max_tick_gap_s, self.max_tick_gap_phase = now - last, str(self.supervisor.phase)
            self.max_tick_cpu_s = max(self.max_tick_cpu_s, cpu - last_cpu)
            last, last_cpu = now, cpu
            self._emit(self.supervisor.tick(self.clock_s()))
            self._between_flights()
            self._watch_preflight()
            if self.notifier is not None and self.notifier.watchdog_s is not None and now >= self._watchdog_due_s:
                self.notifier.watchdog()        # fed by the loop: a loop stalled longer goes unfed
                self._watchdog_due_s = now + self.notifier.watchdog_s
            if self.link is not None and (line := self.link.peer.notice(self.clock_s())) is not None:
                self.log(f"link: {line}")

    def _watch_preflight(self) -> None:
        """Say what the start waits for when it lasts (:class:`~.startup.PreflightWatch`)."""
        sup = self.supervisor
        st = sup.vehicle_status         # read directly: no status report built at every tick
        self._watch.update(None if sup.phase != Phase.PREFLIGHT else preflight_wait(
            self._heard, sup.last_sample is not None, None if st is None else st.armed,
            bool(sup.ctx.pending)), self.clock_s())

    # ---------------------------------------------------------------- requests
    async def offer_text(self, yaml_text: str, source: str) -> dict:
        """Plan an upload in the worker and queue it; a rejection changes nothing."""
        return (await self._offer(yaml_text, source))[0]

    async def _offer(self, yaml_text: str, source: str,
                     before_queue: Callable[[], Awaitable] | None = None) -> tuple[dict, int]:
        """(the response, the exit status a rejection means: :mod:`mavreg.errors`); an accepted
        plan awaits ``before_queue()`` (the start: the kernels its regulator runs) first."""
        if self.supervisor.finished:
            return {"ok": False, "verdict": "rejected", "reason": self._no_flight_reason()}, EXIT_FAILED
        try:
            result = await self.pool.plan(yaml_text, source)
        except PlannerDied as exc:        # refused with its cause; nothing else changes
            self.uploads["rejected"] += 1
            self.log(f"upload {source!r} refused: {exc}")
            return {"ok": False, "verdict": "refused", "reason": str(exc)}, EXIT_FAILED
        if not result.accepted:
            self.uploads["rejected"] += 1
            self.log(f"upload {source!r} rejected: {result.reason}")
            return {"ok": False, "verdict": "rejected", "reason": result.reason}, result.status
        if before_queue is not None:
            await before_queue()
        if self.supervisor.finished or self.supervisor.phase == Phase.TERMINATE:   # ended while planning
            return {"ok": False, "verdict": "rejected", "reason": self._no_flight_reason()}, EXIT_FAILED
        self._emit(self.supervisor.offer_plan(result.plan, self.clock_s()))
        self.uploads["accepted"] += 1
        self.plans.append(result.plan)
        where = "now (at a safe point)" if self.supervisor.at_safe_point() else "at the next safe point (hold)"
        return {"ok": True, "verdict": "accepted", "plan": jsonable(result.plan.summary()),
                "detail": f"{result.plan.name!r} queued; it starts {where}"}, 0

    async def handle_request(self, req: dict) -> dict:
        op = req["op"]
        if op == "upload":
            return await self.offer_text(req["yaml"], req["name"])
        if op == "land":
            self._emit(self.supervisor.request_land(self.clock_s()))
            return {"ok": True, "detail": "landing at the next safe point"}
        return {"ok": True, "status": self.status()}

    def status(self) -> dict:
        """The endpoint's ``status`` answer (:func:`~mavreg.daemon.flight.status.status_report`)."""
        return status_report(self, TICK_S)

    def latency_summary(self, maneuver_only: bool = False) -> dict:
        """Median and 99th percentile (ms) from datagram receipt to the command sent."""
        return latency_summary(self.maneuver_latency_ns if maneuver_only else self.latency_ns)

    def request_stop(self) -> None:
        """Signal handler: first land (if airborne), then stop at once."""
        self._signals += 1
        if self._signals == 1 and self.supervisor.airborne:
            self.log("signal: landing at the next safe point (signal again to stop at once; "
                     "the vehicle's failsafe then lands)")
            self._emit(self.supervisor.request_land(self.clock_s()))
        else:
            self.log("signal: stopping")
            self._stop.set()

    # --------------------------------------------------------------------- run
    async def run(self, initial: list[tuple[str, str]] | None = None, timeout_s: float | None = None,
                  install_signals: bool = True) -> None:
        """Fly until the supervisor finishes, a stop is requested or ``timeout_s`` passes.

        ``initial`` is a list of (yaml_text, source) uploads planned before anything flies.
        """
        loop = asyncio.get_running_loop()
        if install_signals:
            for sig in (signal.SIGINT, signal.SIGTERM):
                loop.add_signal_handler(sig, self.request_stop)
        # the parameters this daemon regulates with, not their files: a restarted worker plans
        # with them even if a file changed since
        self.pool = PlannerPool(self.vehicle, self.config.controller, self.config.planner)
        blas = one_blas_thread()        # at once, for the loop's small products (mavreg/blas.py)
        try:
            await self._start(initial or [])
            if self._tlog_files is not None:
                self._open_tlog()
            self.link = await open_link(self.config.vehicle_url, self.config.supervisor.vehicle_system_id,
                                        self.config.supervisor.vehicle_component_id, self._on_message, self._tlog,
                                        signing=self.signing, on_closed=self.log, on_read_end=self._on_read_end)
            if self.config.gcs_urls:
                await self._open_gcs()
            self._tasks.append(asyncio.create_task(self._heartbeat_task(), name="heartbeat"))
            self._tasks.append(asyncio.create_task(self._tick_task(), name="tick"))
            if self.config.socket_path is not None:
                self.endpoint = EndpointServer(self.config.socket_path, self.handle_request, self.log)
                await self.endpoint.start()
                self.log(f"control endpoint: {self.config.socket_path}")
            self.log(f"link: {self.config.vehicle_url}")
            if self.notifier is not None:
                self.notifier.ready(f"flying from {self.config.vehicle_url}" + (
                    f"; uploads on {self.config.socket_path}" if self.config.socket_path is not None else ""))
            try:
                await asyncio.wait_for(self._stop.wait(), timeout_s)
            except asyncio.TimeoutError:
                self.log(f"timeout after {timeout_s:g} s in phase {self.supervisor.phase}")
        finally:
            await self._shutdown(loop, install_signals)
            blas.__exit__(None, None, None)

    async def _start(self, initial: list[tuple[str, str]]) -> None:
        """Start the planner worker and plan the command line's maneuvers while the kernels
        compile (a thread; the worker is another process), each a stage of :attr:`progress`.
        A rejected maneuver ends the start at once, without waiting for the compile."""
        with self.progress.stage("starting the planner", "started the planner", announce=False):
            warm = asyncio.ensure_future(self.pool.warm_up())
            await asyncio.sleep(0)          # the worker is being started: now the compile
            compiled = asyncio.ensure_future(compile_kernels(self.progress, lambda: warm_daemon_kernels(
                self.vehicle, self.config.control_rate_hz, self.config.controller, self.config.supervisor.hover)))
            try:
                await warm
            except BaseException:
                compiled.cancel()
                raise
        try:
            for text, source in initial:
                cached = text_in_cache(text, source, self.vehicle, self.pool.controller)
                name = source.rsplit("/", 1)[-1]
                doing = f"planning {name}" + ("" if cached is not False else " (not in the plan cache yet)")
                stage = self.progress.stage(doing, f"planned {name}", announce=cached is not True).begin()

                async def planned(stage=stage) -> None:     # the stage ends with the plan, not the compile
                    stage.end()
                    await compiled
                try:
                    verdict, status = await self._offer(text, source, planned)
                finally:
                    stage.end()
                if not verdict["ok"]:
                    raise _InitialRejected(verdict["reason"] if "reason" in verdict else verdict["error"], status)
            await compiled
        except BaseException:
            compiled.cancel()
            raise

    async def _open_gcs(self) -> None:
        """The ground-station endpoints: the vehicle's telemetry and the daemon's messages out,
        the ground station's messages judged by :func:`mavreg.daemon.gcs.policy.judge`."""
        def land() -> None:
            self._emit(self.supervisor.request_land(self.clock_s()))
        # before a system id taken from the vehicle's HEARTBEAT is known, 1; then the vehicle's
        self.gcs = GcsLink(self.config.gcs_urls, self.config.supervisor.vehicle_system_id or 1, self.config.gcs,
                           self.clock_s, lambda: not self.supervisor.finished,
                           lambda msg: self.link is not None and self.link.send(msg), land, self.log)
        await self.gcs.open()
    async def _shutdown(self, loop, signals_installed: bool) -> None:
        if self.notifier is not None:
            self.notifier.stopping(f"stopping in phase {self.supervisor.phase}")
        if self._gap_timer is not None:
            self._gap_timer.cancel()
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        self._tasks.clear()
        if self.endpoint is not None:
            why = f"; {self.supervisor.reason}" if self.supervisor.reason else ""
            await self.endpoint.close(f"the daemon is stopping (phase {self.supervisor.phase}{why})")
        if self.gcs is not None:
            self.gcs.flush()                # the last phase change and STATUSTEXTs
            await self.gcs.aclose()
        if self.link is not None:
            self.link.close()
        if self._tlog is not None:
            self._tlog.close()
        if not self._flight_closed and self.config.flights != 1:
            self._close_flight_on_stop()
        if self.pool is not None:
            self.pool.shutdown()
        if signals_installed:
            for sig in (signal.SIGINT, signal.SIGTERM):
                loop.remove_signal_handler(sig)


class _InitialRejected(UserError):
    """The maneuver given on the command line does not plan: a bad file (exit 2) or a
    maneuver that cannot be flown (exit 1)."""

    def __init__(self, reason: str, status: int):
        super().__init__(reason)
        self.exit_status = status

