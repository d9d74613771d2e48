"""``mavreg warm-up``: compile the kernels and plan the library once, so that the first
``mavreg fly`` or ``serve`` on this machine starts in seconds."""
from __future__ import annotations

import time
from pathlib import Path

from ..config.defaults import CONTROL_RATE_HZ
from ..config.paths import maneuver_files
from .common import REAL_CONTROLLER, add_model_arguments, input_file, positive_float

HELP = "compile the controller's kernels and plan the maneuver library into the caches (once per install)"
DESCRIPTION = """\
On a fresh install the first command that flies compiles the controller's numba kernels and
plans its maneuver: tens of seconds on a laptop, a minute or more on a Raspberry Pi. This
command does both ahead of time, saying each stage as it goes: it compiles (or loads) the
kernels the daemon's loop calls and the planner's, into numba's cache (next to the package,
or $NUMBA_CACHE_DIR), and plans every maneuver given (default: the bundled library,
params/maneuvers/) for the vehicle and controller given, into the plan cache
($MAVREG_PLAN_CACHE, else ~/.cache/mavreg/plans). Afterwards `mavreg fly` on those files
starts in a few seconds. Run it again after an upgrade (the set-up scripts run it after each
install: scripts/venv.sh). A second run with warm caches takes a few seconds.

Run it as the user (and with the environment) the daemon runs as: the caches are per user
(docs/deployment.md for a systemd service).

Exit status: 0 done; 1 a maneuver does not plan (the others are still planned); 2 bad
arguments or files.
"""


def add_arguments(p):
    p.add_argument("maneuvers", metavar="FILE", nargs="*", type=input_file,
                   help="maneuver YAML files to plan (default: every file in the bundled library)")
    p.add_argument("--control-rate-hz", type=positive_float, default=CONTROL_RATE_HZ, metavar="HZ",
                   help="the control rate the daemon will fly at (default %(default)s)")
    add_model_arguments(p, controller=REAL_CONTROLLER)


def run(args) -> int:
    from ..progress import Progress
    progress = Progress(write=_stdout_line, tag="mavreg warm-up")
    progress.line("the controller's kernels, then the maneuvers' plans, into the caches")
    from ..config.controller import load_controller
    from ..config.vehicle import load_vehicle
    from ..control.controllers.hover import HoverParams
    from ..daemon.jobs.startup import kernels_cold, warm_daemon_kernels
    vehicle, controller = load_vehicle(args.vehicle_params), load_controller(args.controller)
    files = [Path(f) for f in args.maneuvers] or maneuver_files()
    cold = kernels_cold()
    with progress.stage("compiling the controller's kernels" if cold else "loading the controller's kernels",
                        "compiled the controller's kernels" if cold else "loaded the controller's kernels"):
        warm_daemon_kernels(vehicle, args.control_rate_hz, controller, HoverParams.from_controller(controller))
    failed = [path for k, path in enumerate(files, 1)
              if not _plan(progress, path, f"{k} of {len(files)}", vehicle, controller)]
    took = time.monotonic() - progress.start_s
    progress.line(f"done: {len(files) - len(failed)} of {len(files)} maneuvers planned in {took:.1f} s"
                  + (f"; not planned: {', '.join(p.name for p in failed)}" if failed else ""))
    return 1 if failed else 0


def _plan(progress, path: Path, which: str, vehicle, controller) -> bool:
    """Plan one file into the cache as a stage; False (and one line) when it does not plan."""
    from ..errors import exit_status_of, one_line
    from ..planning.plan_io import plan_text, text_in_cache
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        progress.line(f"{path}: cannot be read: {one_line(exc)}")
        return False
    cached = text_in_cache(text, str(path), vehicle, controller)
    doing = f"planning {path.name} ({which}" + (", from the plan cache)" if cached else ")")
    try:
        with progress.stage(doing, f"planned {path.name}"):
            plan_text(text, str(path), vehicle, controller)
    except Exception as exc:
        if exit_status_of(exc) is None:
            raise
        progress.line(f"{path.name} does not plan: {one_line(exc)}")
        return False
    return True


def _stdout_line(text: str) -> None:
    print(text, flush=True)
