"""Fly one run with the daemon against firmware_sim in lockstep over MAVLink (``--via sitl``).

Each run is one ``mavreg fly --lockstep --world ideal`` (the paper's world: the true state
at once, no link effects, the vehicle file's 20 ms rotor lag) with the paper's design
(``paper_lqr.yaml``'s gains) on the vehicle file's nominal MK-Quadro (12 N rotors). The run's
plant goes to the emulator alone: ``--inertia-kg-m2``, ``--rotor-noise-sd-n`` (drawn every
1 ms physics step from ``--seed``) and ``--rotor-saturation-n`` (the rotors clip at the
limit while the daemon's commands keep the 12 N scale; ``--max-rotor-thrust-n`` would
rescale the commands too). The controller is told a saturation run's limit (its allocation and speed
governor count on it; the plan keeps the 12 N airframe): a controller file per limit,
``allocation.max_rotor_thrust_n``. The start offset is ``mavreg fly --entry-offset``: the run-in ends
off the path with the entry's velocity and the regulator takes over there. Laps are the
maneuver file's ``laps.count`` (a variant file is written).

The daemon's flight envelope (docs/safety.md) would end these runs by design: the paper
starts 0.85 m across the path and its 7 N runs leave it by 0.8 m with every rotor at its
limit. The experiment's controller file (:func:`prepare_sitl_files`) is ``paper_lqr.yaml``
with the maneuver bounds widened (:data:`EXPERIMENT_ENVELOPE`); gains and everything else
are the paper's. The runs are judged by the emulator's ground truth (:mod:`.record`).

A gust (``gust`` via sitl) is firmware_sim's own force window, ``--wind force:FN,FE,FD@T0:T1``
in the emulator's time. A lockstep flight is deterministic, so the maneuver begins at the same
vehicle time in every flight of a campaign: :func:`prepare_sitl_files` flies one gust-free
reference flight to measure it, each gust run's window is that start plus the run's window,
and each run checks that its maneuver began there (a run whose maneuver began elsewhere is an
error, not a result).

The robustness experiment (:mod:`.robustness`) flies the product as shipped instead: its
experiment's world (``realistic``), its controller file as is (no widened envelope; a rotor
limit told as above), each run's own maneuver file and firmware_sim arguments, the vehicle
file's rotor noise. Its world's noise moves the maneuver's start, so a gust run's reference
flight is the gust-free flight of the run's own noise seed (one per seed).
"""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from ..config.controller import load_controller
from ..config.maneuver import load_maneuver, maneuver_text_with_laps
from ..daemon.jobs.lifeline import wrap_command
from ..model.rotation import quats_to_matrices
from .record import Flight

__all__ = ["maneuver_window", "SitlFiles", "prepare_sitl_files", "fly_sitl", "EXPERIMENT_ENVELOPE", "FLIGHT_FILES",
           "START_TOLERANCE_S"]

EXPERIMENT_ENVELOPE = {
    "maneuver": {"max_position_error_m": 1.5, "max_attitude_error_deg": 45.0,
                 "max_rate_error_rad_s": 6.0, "max_saturated_share": 1.0},
    "thrust_check_min_ratio": 100.0,
    "max_stall_s": 4.0,
}
"""Envelope changes of the experiments' controller file. Maneuver: 1.5 m off the path (half
the loop's diameter; the paper starts 0.85 m across it), 45 deg and 6 rad/s (its start
transient reaches 18 deg and 3.1-3.6 rad/s on the emulator), saturation allowed all the time.
The thrust check (measured thrust under half the commanded) is off: in the saturation runs the
rotors by design do not give what they are told. The progress check allows 4 s without progress
(1 s): a slow gust pushes the governed regulator back along the path for 2-3 s, by design."""

FLIGHT_FILES = ("flight.tlog", "control.npz", "groundtruth.npz")
"""The large files of a flight (about 17 MB together), removed unless kept."""

ENVELOPE_PEAKS_KEPT = 5
"""The flight envelope's bounds a run came closest to, kept in its results (value / limit)."""

FLY_TIMEOUT_S = 900.0
"""Wall seconds one lockstep flight may take (about 15 s on an idle 2-core machine)."""

START_TOLERANCE_S = 0.0015
"""A gust run's maneuver must begin within this of the reference flight's (under a physics step
of 1 ms and a control period of 2 ms: the same sample)."""


@dataclass(frozen=True)
class SitlFiles:
    """The files the daemon flies with: maneuvers by laps, the experiment's controller."""

    maneuvers: dict
    """laps -> maneuver YAML path."""
    controller_path: Path
    vehicle_path: Path
    maneuver_start_s: float | None = None
    """Emulator time at which the maneuver begins (the reference flight's), for gust windows."""
    controllers_by_saturation: tuple = ()
    """(rotor limit N, controller YAML path) of the saturation runs: the experiment's controller
    file told the limit (``allocation.max_rotor_thrust_n``, docs/governor.md)."""
    world: str = "ideal"
    """The emulator's world (``mavreg fly --world``)."""
    starts_by_seed: tuple = ()
    """(noise seed, maneuver start in emulator time): one reference flight per seed, where the
    world's noise moves the start (the realistic world)."""
    reference_failures: tuple = ()
    """(noise seed, why): the reference flights that gave no start; their gust runs are errors."""

    def maneuver_for(self, spec) -> Path:
        """The maneuver file ``spec`` flies: its own (a robustness run's), or the experiment's by laps."""
        own = getattr(spec, "maneuver_path", None)
        return Path(own) if own is not None else self.maneuvers[spec.laps]

    def start_for(self, seed: int) -> float | None:
        """The maneuver's start in emulator time for a run of noise seed ``seed``."""
        return dict(self.starts_by_seed).get(seed, self.maneuver_start_s)

    def controller_for(self, saturation_n: float | None) -> Path:
        """The controller file of a run whose rotors saturate at ``saturation_n`` (None: none)."""
        for limit, path in self.controllers_by_saturation:
            if limit == saturation_n:
                return path
        return self.controller_path


def prepare_sitl_files(exp, out_dir: Path, jobs: int = 1) -> SitlFiles:
    """Write the experiment's controller file and a maneuver file per laps count into
    ``out_dir``, and fly the gust runs' reference flights (``jobs`` at once); every path
    returned is absolute."""
    out_dir = Path(out_dir).resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    ctrl = yaml.safe_load(Path(exp.controller_path).read_text())
    widen = getattr(exp, "widen_envelope", True)    # the robustness experiment flies the file as is
    if widen:
        env = ctrl.setdefault("envelope", {})
        env.update(EXPERIMENT_ENVELOPE)
        ctrl_path = out_dir / "controller_experiment.yaml"
        ctrl_path.write_text(f"# {exp.controller_path} with the maneuver envelope of mavreg experiment\n"
                             "# (mavreg/experiments/via_sitl.py, EXPERIMENT_ENVELOPE): the paper's runs\n"
                             "# leave the path by more than the default 0.5 m on purpose.\n"
                             + yaml.safe_dump(ctrl, sort_keys=False))
    else:
        ctrl_path = Path(exp.controller_path).resolve()
    load_controller(ctrl_path)                      # validated by the one loader
    file_laps = load_maneuver(exp.maneuver_path).laps
    maneuvers = {}
    for laps in sorted({r.laps for r in exp.runs}, key=lambda n: -1 if n is None else n):
        if laps is None or (file_laps is not None and file_laps.count == laps):
            maneuvers[laps] = Path(exp.maneuver_path).resolve()
            continue
        text = maneuver_text_with_laps(Path(exp.maneuver_path).read_text(), laps, str(exp.maneuver_path))
        path = out_dir / f"{Path(exp.maneuver_path).stem}_laps{laps}.yaml"
        path.write_text(f"# {exp.maneuver_path} flown {laps} times round its laps segment\n" + text)
        maneuvers[laps] = path
    told = []
    for limit in sorted({r.saturation_n for r in exp.runs if r.saturation_n is not None}):
        sat = dict(ctrl, allocation={**(ctrl.get("allocation") or {}), "max_rotor_thrust_n": float(limit)})
        path = out_dir / f"{'controller_experiment' if widen else ctrl_path.stem}_rotors{limit:g}n.yaml"
        path.write_text(f"# {ctrl_path.name} told that the rotors give {limit:g} N at most\n"
                        + yaml.safe_dump(sat, sort_keys=False))
        load_controller(path)
        told.append((float(limit), path))
    world = getattr(exp, "world", "ideal")
    files = SitlFiles(maneuvers, ctrl_path, Path(exp.vehicle_path).resolve(),
                      controllers_by_saturation=tuple(told), world=world)
    gusts = [r for r in exp.runs if r.gust_force_n is not None]
    if gusts and world == "ideal":                 # no noise in the world: one reference for all
        files = dataclasses.replace(files, maneuver_start_s=_reference_start(exp.runs[0], files,
                                                                             out_dir / "runs" / "reference"))
    elif gusts:                                    # the noise moves the start: one per seed
        first = sorted({r.seed: r for r in reversed(gusts)}.items())
        with ThreadPoolExecutor(max(1, min(jobs, len(first)))) as pool:     # each flight is a process
            starts = list(pool.map(lambda sr: _start_or_why(sr[1], files, out_dir / "runs" / f"reference-{sr[0]}"),
                                   first))
        files = dataclasses.replace(
            files, starts_by_seed=tuple((seed, t0) for (seed, _), t0 in zip(first, starts) if isinstance(t0, float)),
            reference_failures=tuple((seed, t0) for (seed, _), t0 in zip(first, starts) if isinstance(t0, str)))
    return files


def _start_or_why(run, files: SitlFiles, run_dir: Path) -> float | str:
    """:func:`_reference_start`, or why it failed (one seed's failure does not stop the campaign)."""
    try:
        return _reference_start(run, files, run_dir)
    except (ValueError, OSError, subprocess.SubprocessError) as exc:
        return str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__


def _reference_start(run, files: SitlFiles, run_dir: Path) -> float:
    """Fly ``run`` without its gust into ``run_dir``; its maneuver's start in emulator time."""
    spec = dataclasses.replace(run, gust_force_n=None, gust_window_s=None)
    run_dir.mkdir(parents=True, exist_ok=True)
    with open(run_dir / "fly.log", "w") as log:
        subprocess.run(wrap_command(fly_command(spec, files, run_dir)), stdout=log, stderr=subprocess.STDOUT,
                       cwd=run_dir, timeout=FLY_TIMEOUT_S + 60)
    for name in FLIGHT_FILES:
        (run_dir / name).unlink(missing_ok=True)
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"the gust-free reference flight failed ({run_dir / 'fly.log'}): {exc}") from None
    t0 = maneuver_window(summary["events"])[0]
    if t0 is None:
        raise ValueError(f"the gust-free reference flight never began its maneuver: {summary['reason']}")
    return t0


def fly_command(spec, files: SitlFiles, run_dir: Path) -> list[str]:
    """The ``mavreg fly`` command line of one run."""
    cmd = [sys.executable, "-m", "mavreg.cli.main", "fly", str(files.maneuver_for(spec)),
           "--lockstep", "--world", files.world, "--controller", str(files.controller_for(spec.saturation_n)),
           "--vehicle-params", str(files.vehicle_path), "--out", str(run_dir),
           "--timeout-s", f"{FLY_TIMEOUT_S:g}", "--entry-offset", *(repr(float(v)) for v in spec.offset_m),
           f"--emulator-arg=--seed={spec.seed}"]
    if spec.rotor_noise_sd_n is not None:            # None: the vehicle file's
        cmd.append(f"--emulator-arg=--rotor-noise-sd-n={float(spec.rotor_noise_sd_n)!r}")
    if spec.saturation_n is not None:                # floats as repr: the shortest exact decimal
        cmd.append(f"--emulator-arg=--rotor-saturation-n={float(spec.saturation_n)!r}")
    if spec.inertia_kg_m2 is not None:
        cmd += ["--emulator-arg=--inertia-kg-m2", *(f"--emulator-arg={float(j)!r}" for j in spec.inertia_kg_m2)]
    if spec.gust_force_n is not None:
        start = files.start_for(spec.seed)
        why = dict(files.reference_failures).get(spec.seed)
        if why is not None:
            raise ValueError(f"no gust window: the gust-free reference flight of seed {spec.seed} failed: {why}")
        if start is None:
            raise ValueError("a gust run needs the maneuver's start time of a reference flight")
        a, b = (start + w for w in spec.gust_window_s)
        cmd.append("--emulator-arg=--wind=force:" + ",".join(repr(float(f)) for f in spec.gust_force_n)
                   + f"@{a!r}:{b!r}")
    cmd += [f"--emulator-arg={a}" for a in getattr(spec, "emulator_args", ())]
    return cmd


def maneuver_window(events) -> tuple[float | None, float | None, str | None]:
    """(start, end, phase after) of the maneuver phase, from a flight's events (summary.json's
    ``events``; None where there is none)."""
    t0 = t1 = after = None
    for ev in events:
        if ev["kind"] != "phase" or ev["time_s"] is None:
            continue
        if t0 is None and ev["phase"] == "maneuver":
            t0 = float(ev["time_s"])
        elif t0 is not None and ev["phase"] != "maneuver":
            t1, after = float(ev["time_s"]), ev["phase"]
            break
    return t0, t1, after


def _empty(status: str, reason: str, limit: float, extra: dict) -> Flight:
    z = np.zeros((0, 3))
    return Flight(np.zeros(0), z, np.zeros((0, 3, 3)), z, np.zeros((0, 4)), np.zeros((0, 4)),
                  status, reason, False, limit, extra)


def fly_sitl(spec, files: SitlFiles, run_dir: Path, max_rotor_thrust_n: float,
             keep_files: bool = False, judge=None) -> Flight:
    """Fly ``spec`` with ``mavreg fly`` into ``run_dir``; the emulator's true record of the maneuver.

    ``max_rotor_thrust_n`` is the vehicle file's limit, the plant's when the run does not
    saturate. The flight's output (``summary.json``, ``flight.png``, ``fly.log``) stays in
    ``run_dir``; :data:`FLIGHT_FILES` too with ``keep_files``. ``judge(summary, record_path)``,
    when given, judges the whole flight (take-off to landing) before the recording is removed;
    its dict is the flight's ``extra["flight"]``.
    """
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    limit = spec.saturation_n if spec.saturation_n is not None else max_rotor_thrust_n
    t_wall = time.monotonic()
    with open(run_dir / "fly.log", "w") as log:
        try:
            proc = subprocess.run(wrap_command(fly_command(spec, files, run_dir)), stdout=log,
                                  stderr=subprocess.STDOUT, cwd=run_dir, timeout=FLY_TIMEOUT_S + 60)
            code = proc.returncode
        except subprocess.TimeoutExpired:
            code = None
    extra = {"wall_time_s": time.monotonic() - t_wall, "fly_exit_code": code}
    try:
        summary = json.loads((run_dir / "summary.json").read_text())
        with np.load(run_dir / "groundtruth.npz") as z:
            rec = {k: z[k] for k in ("t_s", "position_ned_m", "quaternion_wxyz", "velocity_ned_m_s",
                                     "rotor_cmd_n", "rotor_applied_n")}
        if judge is not None:
            extra["flight"] = judge(summary, run_dir / "groundtruth.npz")
    except (OSError, ValueError, KeyError) as exc:
        tail = (run_dir / "fly.log").read_text().strip().splitlines()[-1:] or [""]
        return _empty("not_flown", f"mavreg fly exit {code}: {tail[0] or exc}", limit, extra)
    finally:
        if not keep_files:
            for name in FLIGHT_FILES:
                (run_dir / name).unlink(missing_ok=True)
    peaks = (summary.get("status") or {}).get("envelope_peaks") or {}
    top = sorted(peaks.items(), key=lambda kv: -kv[1]["ratio"])[:ENVELOPE_PEAKS_KEPT]
    extra.update(flight_result=summary["result"], flight_reason=summary["reason"],
                 envelope_peaks={k: {f: v[f] for f in ("ratio", "value", "limit", "phase")} for k, v in top})
    t0, t1, after = maneuver_window(summary["events"])
    if t0 is None:
        return _empty("not_flown", summary["reason"] or "the maneuver did not start", limit, extra)
    if spec.gust_force_n is not None:
        start = files.start_for(spec.seed)
        if abs(t0 - start) > START_TOLERANCE_S:
            raise ValueError(f"the maneuver began at {t0:.4f} s of emulator time, not at {start:.4f} s "
                             "as in the reference flight: the gust missed its place")
        extra["gust_window_emulator_s"] = [start + w for w in spec.gust_window_s]
    t = rec["t_s"]
    sel = (t >= t0) & (t <= (t1 if t1 is not None else t[-1]))
    completed = after == "hold"          # the maneuver's end hands over to the exit hold
    status = "completed" if completed else "failed"
    reason = "end of the path reached" if completed else (summary["reason"] or f"maneuver ended in {after}")
    return Flight(t_s=t[sel] - t0, position_m=rec["position_ned_m"][sel],
                  rotation=quats_to_matrices(rec["quaternion_wxyz"][sel]),
                  velocity_m_s=rec["velocity_ned_m_s"][sel], rotor_command_n=rec["rotor_cmd_n"][sel],
                  rotor_applied_n=rec["rotor_applied_n"][sel], status=status, reason=reason,
                  completed=completed, saturation_n=limit, extra=extra)
