"""The ``fly`` job: one maneuver from the ground back to the ground, with its outputs.

With no vehicle URL it spawns ``firmware_sim`` on a free loopback port as a child
process (recording its ground truth), flies, stops the emulator, and writes into the
output directory:

- ``summary.json``: result, the failure (first bound violated, where, by how much, what was
  done), per-segment controller metrics, ground-truth errors, events, and the provenance
  (command line, input files and their SHA-256, software versions: :mod:`mavreg.provenance`);
- ``flight.png``: the path (3-D, top and side views), the true errors against arc length,
  speed, thrust, rotor commands and the whole flight by phase; a failure marked
  (:func:`mavreg.plots.plot_fly`);
- ``flight.tlog``: every MAVLink message in and out (pymavlink format; stamped with the
  vehicle's clock in lockstep, the wall clock in real time);
- ``control.npz``: the controller's internals (see :mod:`mavreg.daemon.jobs.ctrllog`);
- ``groundtruth.npz``: the emulator's recording (bundled emulator only).
"""
from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from ...config.controller import load_controller
from ...config.defaults import CONTROL_RATE_HZ, STALE_TIMEOUT_S
from ...config.maneuver import maneuver_text_with_laps
from ...config.vehicle import load_vehicle, with_dialect, with_output
from ...control.controllers.hover import HoverParams
from ...progress import Progress
from .app import Daemon, DaemonConfig, regulator_factory
from .ctrllog import decoded
from ..flight.excitation import ExcitationParams
from ..gcs.bridge import GcsParams
from .lifeline import wrap_command
from ..vehicle.link import io_impl
from ..vehicle.peers import system_id_to_use
from ...transport.signing import Signing
from .report import controller_metrics, format_summary, ground_truth_errors, plot_flight
from .flight_book import outcome
from ..logs.outputs import write_or_say
from .planner_pool import PlannerBounds
from ..flight.supervisor import Phase, SupervisorParams

__all__ = ["FlyOptions", "fly", "spawn_emulator", "stop_process", "outcome"]

LOCKSTEP_TIMEOUT_S = 2.0
"""Wall seconds the bundled lockstep emulator waits for each period's command."""


@dataclass(frozen=True)
class FlyOptions:
    maneuver_path: Path
    vehicle_url: str | None
    vehicle_path: Path
    controller_path: Path
    out_dir: Path
    socket_path: Path | None
    timeout_s: float
    lockstep: bool
    emulator_args: tuple[str, ...]
    control_rate_hz: float = CONTROL_RATE_HZ
    """The vehicle's telemetry (control) rate; the bundled emulator is started at it."""
    vehicle_lockstep: bool = False
    """The vehicle (``--vehicle``) is a lockstep simulator: no telemetry gaps to fly through."""
    world: str = "realistic"
    """The bundled emulator's world preset: ``realistic`` (link delay, jitter and loss, an
    EKF-like estimate in telemetry) or ``ideal`` (the true state at once: the paper's world)."""
    stale_timeout_s: float = STALE_TIMEOUT_S
    """Wall seconds without a complete sample before the link counts as lost."""
    entry_offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The run-in ends this far (NED) from the maneuver's entry: the regulator takes over off
    the path (experiments; :attr:`mavreg.daemon.flight.phases.SupervisorParams.entry_offset_m`)."""
    signing_key: Path | None = None
    """MAVLink 2 signing key file (:mod:`mavreg.transport.signing`); the bundled emulator gets
    the same file. None: signing off."""
    gcs_urls: tuple[str, ...] = ()
    gcs: GcsParams = GcsParams()
    """Ground stations that watch the flight live (``--gcs``, :mod:`mavreg.daemon.gcs.bridge`)."""
    tlog_clock: str | None = None
    """The ``.tlog``'s timestamps (:attr:`mavreg.daemon.jobs.app.DaemonConfig.tlog_clock`); None:
    the vehicle's clock for a lockstep vehicle (``lockstep`` or ``vehicle_lockstep``), else
    the wall clock."""
    argv: tuple[str, ...] = ()
    """The command line as typed, for the provenance in ``summary.json``."""
    planner: PlannerBounds = PlannerBounds()
    """What one upload may cost the planner worker."""
    output: str | None = None
    """``rotors`` or ``rates`` (what the daemon commands); None: the vehicle file's."""
    laps: int | None = None
    """Fly the maneuver's laps segment this many times (``--laps``); None: as in the file."""
    excitation: ExcitationParams | None = None
    """The identification flight's rate doublets in the hold (``--identify-excitation``,
    :mod:`mavreg.daemon.flight.excitation`); None: none."""
    dialect: str | None = None
    """The mode layout of a vehicle that announces GENERIC (``--dialect``); None: the vehicle
    file's (:func:`mavreg.daemon.vehicle.autopilots.choose_dialect`)."""
    progress: Progress | None = None
    """The start's stage lines (:mod:`mavreg.progress`); None: the daemon's own, from when it
    is built. The command line passes the one it printed its first line with."""
    vehicle_system_id: int | None = None
    """The vehicle's system id (``--vehicle-system-id``); None: taken from its first autopilot
    HEARTBEAT on ``udpin:``, 1 otherwise (:func:`mavreg.daemon.vehicle.peers.system_id_to_use`). The
    bundled emulator is started with it."""
    wall_s: Callable[[], float] = time.time
    """The wall clock (injected: tests step it mid-flight). Only the signing timestamps and the
    ``.tlog``'s first stamp read it; steering and safety run on the monotonic and the
    vehicle's clocks."""
    airborne: str = "land"
    """A vehicle found armed in the air: taken over, then ``land`` or ``fly`` (``--airborne``,
    :attr:`mavreg.daemon.flight.phases.SupervisorParams.airborne`)."""


def spawn_emulator(vehicle_path: Path, record: Path | None, lockstep: bool, extra: tuple[str, ...] = (),
                   timeout_s: float = 20.0, rate_hz: float = CONTROL_RATE_HZ,
                   preset: str = "realistic") -> tuple[subprocess.Popen, str]:
    """Start ``firmware_sim`` on a free loopback port; return (process, ``udpout:`` URL for us).

    The emulator dies with this process however it ends (SIGKILL included): it is started
    through :mod:`.lifeline`'s exec wrapper, which arms the Linux parent-death signal and
    then execs it (same pid). It runs in a session (process group) of its own, so a
    Ctrl-C in the terminal reaches only the daemon, which lands first and then stops the
    emulator (:func:`stop_process`). Call it from a thread that lives as long as the
    flight (the parent-death signal fires when the starting thread ends).
    ``preset`` is the emulator's world (``--world``: ``realistic`` by default; ``ideal``: the
    true state, no link effects); ``extra`` comes after it, so a ``--world`` (or
    ``--lockstep-timeout-s``) there wins.
    """
    cmd = [sys.executable, "-m", "firmware_sim", "--listen", "udpin:127.0.0.1:0", "--quiet",
           "--vehicle-params", str(vehicle_path), "--control-rate-hz", f"{rate_hz:g}", "--world", preset]
    if record is not None:
        cmd += ["--record", str(record)]
    if lockstep:
        # The daemon is the only pacer: a lost period (the default 0.1 s wait missed on a
        # loaded machine) would leave every later command one period late for good.
        cmd += ["--lockstep", "--lockstep-timeout-s", f"{LOCKSTEP_TIMEOUT_S:g}"]
    cmd += list(extra)
    proc = subprocess.Popen(wrap_command(cmd), stdout=subprocess.PIPE, stderr=None, text=True,
                            start_new_session=True)
    deadline = time.monotonic() + timeout_s
    line = ""
    while time.monotonic() < deadline and proc.poll() is None:
        line = proc.stdout.readline()
        if line.startswith("firmware_sim listening on "):
            url = line.split()[-1]
            return proc, url.replace("udpin:", "udpout:", 1)
    stop_process(proc)
    raise RuntimeError(f"firmware_sim did not start (last line {line!r}, exit {proc.returncode})")


def stop_process(proc: subprocess.Popen, timeout_s: float = 20.0) -> int:
    """SIGINT (the emulator saves its recording), then SIGKILL if it does not exit."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()
    return proc.returncode


def fly(opts: FlyOptions) -> int:
    """Run the whole job; returns the process exit code (0 success, 1 flight failed)."""
    io_impl()          # a bad MAVREG_IO is the user's mistake: one line before anything starts
    text = opts.maneuver_path.read_text()
    if opts.laps is not None:
        text = maneuver_text_with_laps(text, opts.laps, str(opts.maneuver_path))
    vehicle = with_dialect(with_output(load_vehicle(opts.vehicle_path), opts.output), opts.dialect)
    controller = load_controller(opts.controller_path)
    opts.out_dir.mkdir(parents=True, exist_ok=True)
    record_path = opts.out_dir / "groundtruth.npz"
    config = DaemonConfig(vehicle_url=opts.vehicle_url or "", vehicle_path=opts.vehicle_path,
                          controller_path=opts.controller_path, socket_path=opts.socket_path,
                          tlog_path=opts.out_dir / "flight.tlog",
                          supervisor=SupervisorParams(system_id_to_use(opts.vehicle_url, opts.vehicle_system_id),
                                                      land_when_done=True, airborne=opts.airborne,
                                                      stale_timeout_s=opts.stale_timeout_s,
                                                      gap_fill=not (opts.lockstep or opts.vehicle_lockstep),
                                                      lockstep=opts.lockstep or opts.vehicle_lockstep,
                                                      entry_offset_m=tuple(opts.entry_offset_m),
                                                      excitation=opts.excitation,
                                                      hover=HoverParams.from_controller(controller)),
                          envelope=controller.envelope,
                          controller=controller, control_rate_hz=opts.control_rate_hz,
                          gcs_urls=tuple(opts.gcs_urls), gcs=opts.gcs,
                          tlog_clock=opts.tlog_clock or ("vehicle" if opts.lockstep or opts.vehicle_lockstep
                                                         else "wall"),
                          planner=opts.planner)
    make_regulator = regulator_factory(vehicle, opts.control_rate_hz, controller.disturbance,
                                      controller.allocation, controller.speed_governor, warm=False)
    signing = Signing(opts.signing_key, "mavreg", opts.wall_s) if opts.signing_key is not None else None
    daemon = Daemon(config, vehicle, make_regulator, signing=signing, progress=opts.progress, wall_s=opts.wall_s)
    progress = daemon.progress
    extra = tuple(opts.emulator_args)
    if opts.vehicle_system_id is not None:
        extra = ("--vehicle-system-id", str(opts.vehicle_system_id)) + extra
    if opts.signing_key is not None:
        extra = ("--signing-key", str(opts.signing_key)) + extra
    proc = None
    emulator_code = None
    t0 = time.monotonic()
    try:
        async def main():
            nonlocal proc
            if opts.vehicle_url is None:
                with progress.stage("starting the bundled emulator", "started the emulator", announce=False):
                    proc, url = spawn_emulator(opts.vehicle_path, record_path, opts.lockstep,
                                               extra, rate_hz=opts.control_rate_hz,
                                               preset=opts.world)
                daemon.config = replace(config, vehicle_url=url)
            await daemon.run([(text, str(opts.maneuver_path))], timeout_s=opts.timeout_s)
        asyncio.run(main())
    finally:
        if proc is not None:
            emulator_code = stop_process(proc)
    wall_s = time.monotonic() - t0
    with progress.stage("writing the outputs (summary.json, flight.png)", "wrote the outputs", announce=False):
        arrays = daemon.ctrl_log.arrays()
        written = write_or_say("control log", opts.out_dir / "control.npz",
                               lambda: daemon.ctrl_log.save(opts.out_dir / "control.npz", arrays), daemon.log,
                               "the flight's outcome is printed below")
        summary, lines = _finish(opts, daemon, decoded(arrays), record_path if proc is not None else None,
                                 emulator_code, wall_s, {"control.npz": written})
    print("\n".join(lines), flush=True)
    return 0 if summary["result"] == "ok" else 1


def _finish(opts, daemon, ctrl, record_path, emulator_code, wall_s, written) -> tuple[dict, list[str]]:
    """Write summary.json and flight.png; (the summary, the lines to print).

    ``written``: whether each output written before (``control.npz``) made it. A file that
    cannot be written is said once (:func:`mavreg.daemon.logs.outputs.write_or_say`) and left out
    of the ``outputs:`` line; a summary that cannot be written is printed whole instead."""
    sup = daemon.supervisor
    plan = daemon.plans[0] if daemon.plans else None
    failure = outcome(sup, emulator_code, opts.timeout_s)
    ok = failure is None
    events = ctrl["events"]
    man = [e for e in events if e["kind"] == "phase" and e["phase"] == Phase.MANEUVER]
    after = [e for e in events if e["kind"] == "phase" and man and e["time_s"] is not None
             and e["time_s"] > man[0]["time_s"]]
    summary = {
        "result": "ok" if ok else "failed",
        "reason": "" if ok else failure.line(),
        "failure": None if ok else failure.as_dict(),
        "touchdown_speed_m_s": sup.status()["touchdown_speed_m_s"],
        "maneuver": plan.name if plan else str(opts.maneuver_path),
        "length_m": plan.length_m if plan else float("nan"),
        "margins": plan.margins.as_dict() if plan is not None and plan.margins is not None else None,
        "flight_time_s": float(ctrl["t_s"][-1] - ctrl["t_s"][0]) if ctrl["t_s"].size else 0.0,
        "wall_time_s": wall_s,
        "emulator_exit_code": emulator_code,
        "controller_metrics": controller_metrics(ctrl, plan, daemon.vehicle.max_rotor_thrust_n) if plan else {},
        "ground_truth": None,
        "status": daemon.status(),
        "latency_ms": daemon.latency_summary(),
        "maneuver_latency_ms": daemon.latency_summary(maneuver_only=True),
        "events": events,
        "provenance": _provenance(opts),
    }
    record = None
    if record_path is not None and record_path.exists() and plan is not None:
        with np.load(record_path) as z:     # the figure draws the truth of a refused flight too
            record = {k: z[k] for k in ("t_s", "position_ned_m", "quaternion_wxyz", "velocity_ned_m_s")}
    if record is not None and man:
        t_end = after[0]["time_s"] if after else float(record["t_s"][-1])
        summary["ground_truth"] = ground_truth_errors(record, plan, man[0]["time_s"], t_end)
    text = json.dumps(summary, indent=1, default=_plain)
    written["summary.json"] = write_or_say("summary", opts.out_dir / "summary.json",
                                           lambda: (opts.out_dir / "summary.json").write_text(text), daemon.log,
                                           "the summary is printed on standard output instead")
    if plan is not None and ctrl["t_s"].size:
        where = f"the bundled emulator's {opts.world} world" if opts.vehicle_url is None else opts.vehicle_url
        written["flight.png"] = write_or_say("plot", opts.out_dir / "flight.png", lambda: plot_flight(
            opts.out_dir / "flight.png", ctrl, plan, record, summary,
            f"{plan.name} flown by mavreg fly on {where}{', lockstep' if opts.lockstep else ''}, "
            f"controller {opts.controller_path.name}"), daemon.log, "the flight's outcome is printed below")
    written["flight.tlog"] = not (summary["status"].get("tlog") or {}).get("stopped")
    files = ["summary.json", "flight.png", "flight.tlog", "control.npz"] + (
        ["groundtruth.npz"] if record_path is not None else [])
    missing = [f for f in files if not written.get(f, True)]
    lines = [format_summary(summary),
             f"outputs: {opts.out_dir}/ ({', '.join(f for f in files if f not in missing)})"
             + (f"; not written: {', '.join(missing)}" if missing else "")]
    if not written["summary.json"]:
        lines.append("summary.json: " + json.dumps(summary, default=_plain, separators=(",", ":")))
    if not ok:
        lines.append(f"flight failed: {failure.line()}")
    return summary, lines


def _provenance(opts: FlyOptions) -> dict:
    """The command, the input files and their hashes, the software (:mod:`mavreg.provenance`)."""
    from ...provenance import provenance
    world = None
    if opts.vehicle_url is None:
        world = " ".join([f"firmware_sim --world {opts.world}", *(["--lockstep"] if opts.lockstep else []),
                          *opts.emulator_args])
    return provenance(opts.argv or sys.argv, {"maneuver": opts.maneuver_path, "vehicle": opts.vehicle_path,
                                              "controller": opts.controller_path}, world)


def _plain(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return os.fspath(obj)
    raise TypeError(type(obj).__name__)
