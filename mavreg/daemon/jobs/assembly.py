"""One daemon for ``fly`` and ``serve``: the options it is built from (:class:`DaemonOptions`,
built once by keyword from the command line, the files loaded) and the one function that
builds it from them (:func:`assemble`).

``mavreg fly`` and ``mavreg serve`` differ only in their options: ``fly`` gives maneuvers to
plan before anything flies, lands after them, flies one flight and may start the bundled
emulator (:class:`EmulatorOptions`); ``serve`` waits for uploads, flight after flight. The
options hold loaded objects (the vehicle, the controller, the maneuvers' texts), never the
paths beside them: nothing after the command line reads a parameter file again. The one path
to a parameter file is the bundled emulator's (another program, which reads its own).

This module imports no MAVLink, numba or event loop (the command line builds the options
before its first line); :func:`assemble` imports the daemon when it is called.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable

from ...config.controller import ControllerParams
from ...config.defaults import CONTROL_RATE_HZ, STALE_TIMEOUT_S
from ...config.vehicle import VehicleParams
from ...progress import Progress
from ..flight.excitation import ExcitationParams
from ..gcs.params import GcsParams
from .planner_pool import PlannerBounds

if TYPE_CHECKING:
    from .app import Daemon

__all__ = ["DaemonOptions", "EmulatorOptions", "assemble", "TLOG_NAME", "CONTROL_LOG_NAME"]

TLOG_NAME = "flight.tlog"
"""The ``.tlog``'s name in the output directory (``serve``: ``flight-0001.tlog``, ... per flight)."""
CONTROL_LOG_NAME = "control.npz"
"""The controller log's name in the output directory (``serve``: numbered per flight likewise)."""


@dataclass(frozen=True, kw_only=True)
class EmulatorOptions:
    """The bundled emulator (``fly`` without ``--vehicle``), started as a child process."""

    vehicle_file: Path
    """The vehicle file the emulator reads itself (it is another program, with its own loader)."""
    world: str = "realistic"
    """Its world preset (``--world``)."""
    lockstep: bool = False
    """Run it in lockstep (``--lockstep``): the daemon is then its only pacer."""
    args: tuple[str, ...] = ()
    """Extra emulator arguments (``--emulator-arg``), after the world."""


@dataclass(frozen=True, kw_only=True)
class DaemonOptions:
    """What ``fly`` and ``serve`` build their daemon from: one object, by keyword, loaded once.

    A field holds either a loaded object or a path to write, never both for one thing
    (:meth:`__post_init__` refuses a path where an object belongs)."""

    vehicle: VehicleParams
    """The vehicle file, loaded, with ``--output`` and ``--dialect`` applied."""
    controller: ControllerParams
    """The controller file, loaded: the regulator's, the hover's, the envelope's, the
    prediction's and the planner worker's parameters."""
    vehicle_url: str | None
    """The vehicle's URL (``--vehicle``); None: the bundled emulator (:attr:`emulator`)."""
    emulator: EmulatorOptions | None = None
    maneuvers: tuple[tuple[str, str], ...] = ()
    """(text, source) of the maneuvers planned before anything flies (``fly``); none for ``serve``."""
    out_dir: Path | None = None
    """Where the ``.tlog`` and the controller log go (:data:`TLOG_NAME`, :data:`CONTROL_LOG_NAME`;
    numbered per flight when :attr:`flights` is not 1). None: no logs."""
    tlog_file: Path | None = None
    """``serve --tlog FILE`` (deprecated): the ``.tlog`` there instead of in :attr:`out_dir`."""
    control_log_file: Path | None = None
    """``serve --control-log FILE`` (deprecated): the controller log there instead."""
    keep_logs: int = 20
    """Of numbered logs, the newest this many stay (``--keep-logs``)."""
    socket_path: Path | None = None
    """The control endpoint (``--socket``); None: none."""
    flights: int | None = 1
    """Flights before the daemon stops: 1 (``fly``, ``serve --once``), None: until stopped."""
    land_when_done: bool = True
    """Land once the queued maneuvers are flown (``fly``); False: hold and wait (``serve``)."""
    timeout_s: float | None = None
    """Give up after this many wall seconds (``fly --timeout-s``); None: never."""
    control_rate_hz: float = CONTROL_RATE_HZ
    """The vehicle's telemetry and control rate: the regulator's period, the prediction's step
    and the bundled emulator's rate, all from this one field."""
    stale_timeout_s: float = STALE_TIMEOUT_S
    vehicle_lockstep: bool = False
    """``--vehicle-lockstep``: the vehicle is a lockstep simulator (see :attr:`lockstep`)."""
    tlog_clock: str | None = None
    """``vehicle`` or ``wall``; None: the vehicle's for a lockstep vehicle, else the wall's."""
    vehicle_system_id: int | None = None
    airborne: str = "land"
    entry_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    excitation: ExcitationParams | None = None
    signing_key: Path | None = None
    """MAVLink 2 signing key file (the bundled emulator gets the same); None: signing off."""
    gcs_urls: tuple[str, ...] = ()
    gcs: GcsParams = field(default_factory=GcsParams)
    planner: PlannerBounds = field(default_factory=PlannerBounds)
    job_writes_outputs: bool = False
    """The job writes the flight's outputs itself after it (``fly``: ``control.npz`` beside
    ``summary.json`` and ``flight.png``, from the controller log the daemon keeps in memory);
    False: the daemon writes each flight's controller log into :attr:`out_dir` (``serve``)."""
    systemd: bool = False
    """Speak systemd's readiness protocol (``serve``; :mod:`.sdnotify`)."""
    provenance: dict | None = None
    """How the flight was asked for (``fly``'s ``summary.json``; :mod:`mavreg.provenance`):
    taken when the files were loaded."""
    progress: Progress = field(default_factory=Progress)
    """The start's stage lines; its start is the daemon's (the command line passes the one it
    printed its first line with)."""
    wall_s: Callable[[], float] = time.time
    """The wall clock (tests step it): the signing timestamps and the ``.tlog``'s first stamp."""

    def __post_init__(self):
        for name, kind in (("vehicle", VehicleParams), ("controller", ControllerParams)):
            if not isinstance(getattr(self, name), kind):
                raise TypeError(f"DaemonOptions.{name}: a loaded {kind.__name__}, got "
                                f"{type(getattr(self, name)).__name__} (load the file once, then pass it)")
        if (self.vehicle_url is None) != (self.emulator is not None):
            raise ValueError("DaemonOptions: a vehicle URL or the bundled emulator, exactly one")

    @property
    def lockstep(self) -> bool:
        """The vehicle waits for each command: the bundled emulator in lockstep, or a
        ``--vehicle-lockstep`` vehicle (no telemetry gaps are flown on the prediction)."""
        return self.vehicle_lockstep or (self.emulator is not None and self.emulator.lockstep)

    def log_paths(self) -> tuple[Path | None, Path | None]:
        """(the ``.tlog``, the controller log the daemon saves per flight): in :attr:`out_dir`,
        or the deprecated files; None: not written (by the daemon)."""
        out = self.out_dir
        ctrl = None if out is None or self.job_writes_outputs else out / CONTROL_LOG_NAME
        return (self.tlog_file or (out / TLOG_NAME if out is not None else None), self.control_log_file or ctrl)


def assemble(opts: DaemonOptions, vehicle_url: str | None = None) -> "Daemon":
    """The daemon of ``opts``: its config, vehicle, regulator factory, signing, ground
    stations, logs and planner bounds (``fly`` and ``serve`` alike). ``vehicle_url``: the
    bundled emulator's, once it listens (``opts.vehicle_url`` otherwise)."""
    from ...control.controllers.hover import HoverParams
    from ...transport.signing import Signing
    from ..flight.supervisor import SupervisorParams
    from ..vehicle.peers import system_id_to_use
    from .app import Daemon, DaemonConfig
    from .sdnotify import Notifier
    tlog, ctrl_log = opts.log_paths()
    lockstep = opts.lockstep
    supervisor = SupervisorParams(system_id_to_use(opts.vehicle_url, opts.vehicle_system_id),
                                  land_when_done=opts.land_when_done, airborne=opts.airborne,
                                  stale_timeout_s=opts.stale_timeout_s, gap_fill=not lockstep, lockstep=lockstep,
                                  entry_offset_m=tuple(opts.entry_offset_m), excitation=opts.excitation,
                                  hover=HoverParams.from_controller(opts.controller))
    config = DaemonConfig(vehicle_url=vehicle_url or opts.vehicle_url or "", controller=opts.controller,
                          socket_path=opts.socket_path, tlog_path=tlog, supervisor=supervisor,
                          envelope=opts.controller.envelope, control_rate_hz=opts.control_rate_hz,
                          gcs_urls=opts.gcs_urls, gcs=opts.gcs, planner=opts.planner,
                          tlog_clock=opts.tlog_clock or ("vehicle" if lockstep else "wall"),
                          flights=opts.flights, control_log_path=ctrl_log,
                          keep_control_log=opts.job_writes_outputs or ctrl_log is not None,
                          keep_logs=opts.keep_logs)
    signing = Signing(opts.signing_key, "mavreg", opts.wall_s) if opts.signing_key is not None else None
    notifier = Notifier() if opts.systemd else None     # systemd's Type=notify; nothing outside it
    progress = opts.progress
    if notifier is not None:
        progress.write = _with_status(progress.write, notifier)
    return Daemon(config, opts.vehicle, signing=signing, progress=progress, notifier=notifier, wall_s=opts.wall_s)


def _with_status(write, notifier):
    """``write``, each line also systemd's STATUS (``systemctl status`` shows the start)."""
    if not notifier.enabled:
        return write

    def both(line: str) -> None:
        write(line)
        notifier.status(line.split("setup: ", 1)[-1])
    return both
