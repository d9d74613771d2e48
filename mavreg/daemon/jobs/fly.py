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
from pathlib import Path

import numpy as np

from ...config.defaults import CONTROL_RATE_HZ
from .assembly import DaemonOptions, assemble
from .ctrllog import decoded
from .lifeline import wrap_command
from ..vehicle.link import io_impl
from .report import controller_metrics, format_summary, ground_truth_errors, plot_flight
from .flight_book import outcome
from ..logs.outputs import write_or_say
from ..flight.supervisor import Phase

__all__ = ["fly", "spawn_emulator", "stop_process", "outcome"]

LOCKSTEP_TIMEOUT_S = 2.0
"""Wall seconds the bundled lockstep emulator waits for each period's command."""


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


def fly(opts: DaemonOptions) -> int:
    """Run the whole job; returns the process exit code (0 success, 1 flight failed).

    ``opts`` (built by :func:`mavreg.cli.daemon_args.daemon_options`) gives the maneuvers, the
    output directory and, without a vehicle URL, the bundled emulator."""
    io_impl()          # a bad MAVREG_IO is the user's mistake: one line before anything starts
    opts.out_dir.mkdir(parents=True, exist_ok=True)
    emulator = opts.emulator
    record_path = opts.out_dir / "groundtruth.npz" if emulator is not None else None
    proc, emulator_code, daemon = None, None, None
    t0 = time.monotonic()
    try:
        async def main():
            nonlocal proc, daemon
            url = None
            if emulator is not None:
                with opts.progress.stage("starting the bundled emulator", "started the emulator", announce=False):
                    proc, url = spawn_emulator(emulator.vehicle_file, record_path, emulator.lockstep,
                                               _emulator_args(opts), rate_hz=opts.control_rate_hz,
                                               preset=emulator.world)
            daemon = assemble(opts, vehicle_url=url)
            await daemon.run(opts.maneuvers, timeout_s=opts.timeout_s)
        asyncio.run(main())
    finally:
        if proc is not None:
            emulator_code = stop_process(proc)
    wall_s = time.monotonic() - t0
    with daemon.progress.stage("writing the outputs (summary.json, flight.png)", "wrote the outputs",
                               announce=False):
        arrays = daemon.ctrl_log.arrays()
        written = write_or_say("control log", opts.out_dir / "control.npz",
                               lambda: daemon.ctrl_log.save(opts.out_dir / "control.npz", arrays), daemon.log,
                               "the flight's outcome is printed below")
        summary, lines = _finish(opts, daemon, decoded(arrays), record_path, emulator_code, wall_s,
                                 {"control.npz": written})
    print("\n".join(lines), flush=True)
    return 0 if summary["result"] == "ok" else 1


def _emulator_args(opts: DaemonOptions) -> tuple[str, ...]:
    """The bundled emulator's arguments beyond its world: the vehicle's system id, the signing
    key and ``--emulator-arg``."""
    extra = tuple(opts.emulator.args)
    if opts.vehicle_system_id is not None:
        extra = ("--vehicle-system-id", str(opts.vehicle_system_id)) + extra
    if opts.signing_key is not None:
        extra = ("--signing-key", str(opts.signing_key)) + extra
    return extra


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
        "maneuver": plan.name if plan else opts.maneuvers[0][1],
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
        "provenance": opts.provenance,
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
        emulator = opts.emulator
        where = f"the bundled emulator's {emulator.world} world" if emulator is not None else opts.vehicle_url
        written["flight.png"] = write_or_say("plot", opts.out_dir / "flight.png", lambda: plot_flight(
            opts.out_dir / "flight.png", ctrl, plan, record, summary,
            f"{plan.name} flown by mavreg fly on {where}{', lockstep' if opts.lockstep else ''}, "
            f"controller {_controller_name(opts)}"), daemon.log, "the flight's outcome is printed below")
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


def _controller_name(opts: DaemonOptions) -> str:
    """The controller file's name, as the provenance recorded it."""
    path = ((opts.provenance or {}).get("files", {}).get("controller") or {}).get("path")
    return Path(path).name if path else "(given)"


def _plain(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return os.fspath(obj)
    raise TypeError(type(obj).__name__)
