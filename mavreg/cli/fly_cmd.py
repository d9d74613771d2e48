"""``mavreg fly``: the main job, one maneuver from the ground back to the ground."""
from __future__ import annotations

import math
import time
from pathlib import Path

from ..errors import UsageError
from .common import (add_entry_offset_argument, add_laps_argument, check_output_dir, input_file, load_maneuver_arg,
                     output_dir, positive_float, socket_path, vehicle_url, vehicle_url_help)
from .daemon_args import OUT_HELP, add_daemon_arguments, daemon_options

MAX_ENTRY_OFFSET_M = 2.0
"""Longest --entry-offset: an experiment's start error, not a relocation of the maneuver."""

HELP = "fly a maneuver YAML on a vehicle (default: the bundled firmware_sim) and report"
DESCRIPTION = """\
Plan the maneuver (in a worker process), connect to the vehicle over MAVLink 2, stream the
idle setpoint, arm, switch to OFFBOARD, take off to the hold point before the maneuver's
entry, fly it with the maneuver regulator, stop and hold at the exit, land and disarm.
Hold, take-off and landing use a hover LQR from the same design model.

With no --vehicle, the bundled emulator (firmware_sim) is started on a free loopback port
as a child process (real time; --lockstep for a deterministic faster-than-real-time run)
and its ground-truth recording is used for the true tracking error. Its world is a real
vehicle's by default (--world realistic: link delay, jitter and loss, an EKF-like estimate in
telemetry, 20 ms rotor lag, RotorPy-sized drag; wind3, wind6 and thrust90 add a wind or a
thrust loss); --world ideal sends the true state at once (the paper's world).

The default controller (params/controller/realistic.yaml) measures the link's delay with
TIMESYNC, predicts every sample across it before regulating, flies gains designed with the
rotor lag, estimates the airframe's drag, a steady wind force and its thrust scale in flight
and flies the nominal compensated for them, and in real time flies short telemetry gaps on
the prediction (docs/robustness.md). A vehicle calibrated by 'mavreg identify'
(--vehicle-params) feeds a known drag forward in the plan itself. The paper's design:
--controller params/controller/paper_lqr.yaml.

Outputs go to --out DIR (default: flights/<YYYYmmdd-HHMMSS>/): summary.json (results,
events, and the provenance: command line, input files and their SHA-256, versions, git
commit), flight.png (the path in 3-D, top and side views, the TRUE errors against arc length
on a log scale with the controller's own beside them, speed, thrust, rotor commands, the
whole flight by phase; a failed flight says why in the title and is marked where it failed),
flight.tlog (every MAVLink message in and out; mavlogdump.py, mavflightmodes.py, MAVExplorer
and MAVProxy read it; stamped with the vehicle's clock in lockstep, see --tlog-clock),
control.npz (s, w, u, rotor commands and phase per control step), groundtruth.npz (bundled
emulator only).

A per-segment table is printed (a line under it says the same): e_t is the transverse
error, the distance from the path, in mm (max and RMS as the controller estimated it;
"true" from the emulator's ground truth); att the attitude error angle in deg ("true att"
is taken against the plan's drag-free nominal attitude, so it includes the tilt flown on
purpose against drag and wind: about 23 deg on the barrel roll's 8 m/s run-up in the
realistic world); peak rotor the largest rotor force command in N; sat the time a rotor
spent at its limit in s. Events give the vehicle's time (t) and the time since the daemon
started (daemon).

Rotor commands are SET_ACTUATOR_CONTROL_TARGET group 0 with a pass-through mixer
(controls[0..3] = rotors 1..4 front, right, back, left, as a fraction of the maximum rotor
thrust): this is not PX4 v1.13's default attitude mixer.

Every sample is checked against a flight envelope (docs/safety.md): off the path or the hover
point, attitude, rates, altitude floor, geofence, progress, rotor saturation, impact,
telemetry that contradicts itself. A violated bound starts a recovery (level, brake, climb,
hold, then land); an impact or a failed recovery stops the motors (forced disarm). Each
action is also sent to the vehicle as a STATUSTEXT.

Exit status: 0 the maneuver was flown within its envelope and the vehicle landed (touchdown
under 1 m/s) and disarmed; 1 the flight failed: the first bound violated (where, by how much,
what was done) is printed in one line and kept in summary.json under "failure" (also: the
maneuver cannot be flown, or a check before take-off refused it: the vehicle's autopilot or
--dialect, a parameter, the plan outside the envelope, the link; then fly ends within 2 s of
the refusal); 2 bad file or arguments (--out and --socket are checked before
anything starts).
"""


def add_arguments(p):
    p.add_argument("maneuver", metavar="FILE", type=input_file, help="maneuver YAML (kind: maneuver)")
    add_laps_argument(p)
    p.add_argument("--vehicle", metavar="URL", type=vehicle_url, default=None,
                   help=vehicle_url_help("start the bundled firmware_sim on a free loopback port"))
    p.add_argument("--out", metavar="DIR", type=output_dir, default=None,
                   help=f"{OUT_HELP}: summary.json, flight.png, flight.tlog, control.npz, groundtruth.npz "
                   "(default: flights/<timestamp>/)")
    p.add_argument("--socket", metavar="PATH", type=socket_path, default=None,
                   help="also accept uploads on this Unix socket during the flight (default: none)")
    p.add_argument("--timeout-s", type=positive_float, default=300.0, metavar="S",
                   help="give up (exit 1) after this many wall seconds (default: %(default)s)")
    p.add_argument("--world", choices=("realistic", "wind3", "wind6", "thrust90", "ideal"),
                   default="realistic",
                   help="bundled emulator only: 'realistic' (default) gives it a real vehicle's "
                   "link (10 ms down, 5 ms up, +-3 ms, 1%% loss), an EKF-like estimate in its "
                   "telemetry and RotorPy-sized drag; 'wind3' and 'wind6' add a steady 3 or 6 m/s "
                   "wind from the north (turn it with --emulator-arg=--wind-from-deg=DEG), "
                   "'thrust90' rotors that give 90%% of their command; 'ideal' sends the true "
                   "state at once, no drag, the paper's world (reproductions: with --controller "
                   "params/controller/paper_lqr.yaml). See docs/firmware_sim.md and docs/robustness.md")
    p.add_argument("--lockstep", action="store_true",
                   help="bundled emulator only: run it in lockstep (faster than real time)")
    p.add_argument("--tlog-clock", choices=("vehicle", "wall"), default=None,
                   help="the flight.tlog's timestamps: the vehicle's clock (the default with "
                   "--lockstep or --vehicle-lockstep: log tools then show the flight's own "
                   "durations) or the wall clock (the default in real time)")
    p.add_argument("--emulator-arg", action="append", default=[], metavar="ARG",
                   help="bundled emulator only: extra firmware_sim argument (repeatable), "
                   "e.g. --emulator-arg=--rotor-time-constant-s=0")
    add_entry_offset_argument(
        p, "start the maneuver off its path: the hold point and the end of the run-in move by "
        "this NED offset (m, at most %g m) from the entry, with the entry's velocity, and the "
        "regulator takes over there (the paper's Section 4: 0.6 0.6 0.6; more than 0.5 m across "
        "the path needs a controller file whose envelope allows it, see mavreg experiment)"
        % MAX_ENTRY_OFFSET_M)
    add_daemon_arguments(p, bundled_emulator=True)


def run(args) -> int:
    from ..progress import Progress
    progress = Progress()       # the daemon's clock starts with the command
    maneuver = Path(args.maneuver)
    out = Path(args.out) if args.out else Path("flights") / time.strftime("%Y%m%d-%H%M%S")
    if args.vehicle is not None:
        if args.lockstep or args.emulator_arg or args.world != "realistic":
            raise UsageError("--lockstep, --world and --emulator-arg apply only to the bundled "
                             "emulator (no --vehicle)")
    offset = tuple(float(v) for v in args.entry_offset)
    if math.hypot(*offset) > MAX_ENTRY_OFFSET_M:
        raise UsageError(f"--entry-offset must be at most {MAX_ENTRY_OFFSET_M:g} m long, "
                         f"got {' '.join(f'{v:g}' for v in offset)}")
    opts = daemon_options(args, progress, maneuvers=(_maneuver(args),), out_dir=out, job_writes_outputs=True,
                          emulator=_emulator(args), socket_path=Path(args.socket) if args.socket else None,
                          timeout_s=args.timeout_s, tlog_clock=args.tlog_clock, entry_offset_m=offset,
                          provenance=_provenance(args))
    why = check_output_dir(str(out))    # the default --out too, before the flight
    if why is not None:
        raise UsageError(f"--out {why}")
    # checked (a refusal is one line and no other; the checks import no MAVLink, scipy or
    # numba): the first line, before the daemon's imports and everything slow
    where = args.vehicle or ("the bundled emulator" + (" (lockstep)" if args.lockstep else ""))
    progress.line(f"starting: {maneuver.name} on {where}; outputs in {out}/")
    from ..daemon.jobs.fly import fly
    return fly(opts)


def _maneuver(args) -> tuple[str, str]:
    """(the maneuver's text, its source) with ``--laps`` applied; a bad file or ``--laps``: one
    line before anything starts."""
    from ..config.maneuver import maneuver_text_with_laps
    load_maneuver_arg(args)
    text = Path(args.maneuver).read_text()
    if args.laps is not None:
        text = maneuver_text_with_laps(text, args.laps, args.maneuver)
    return text, args.maneuver


def _emulator(args):
    """The bundled emulator's options (None with ``--vehicle``)."""
    if args.vehicle is not None:
        return None
    from ..daemon.jobs.assembly import EmulatorOptions
    return EmulatorOptions(vehicle_file=Path(args.vehicle_params), world=args.world, lockstep=args.lockstep,
                           args=tuple(args.emulator_arg))


def _provenance(args) -> dict:
    """The command, the input files and their hashes, the software (:mod:`mavreg.provenance`)."""
    import sys

    from ..provenance import provenance
    world = None
    if args.vehicle is None:
        world = " ".join([f"firmware_sim --world {args.world}", *(["--lockstep"] if args.lockstep else []),
                          *args.emulator_arg])
    return provenance(tuple(getattr(args, "command_line", ())) or sys.argv,
                      {"maneuver": Path(args.maneuver), "vehicle": Path(args.vehicle_params),
                       "controller": Path(args.controller)}, world)
