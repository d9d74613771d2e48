"""Options the commands share: the vehicle and controller files, and typed converters.

The converters (``type=`` of an argparse option) refuse a bad value while the command line
is parsed, before any work, with one line (``mavreg CMD: error: argument --X: ...``, exit
2): numbers (:func:`positive_float`, :func:`nonneg_float`, :func:`finite_float`,
:func:`positive_int`), files to read (:func:`input_file`: exists, is a regular file, is
readable) and places to write (:func:`output_file`, :func:`output_dir`: the directory
exists or can be created, and is writable), so that a typo in ``--plot`` does not cost the
simulation it follows.
"""
from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from .vehicle_link import check_vehicle_link, vehicle_url, vehicle_url_help
# The old spellings' action is shared with firmware-sim: its home is the neutral module.
from ..deprecated_options import DeprecatedAlias, add_deprecated_alias
# The bundled parameter files have one home, mavreg.config.paths; re-exported for the commands.
from ..config.paths import (DEFAULT_VEHICLE, DESIGN_CONTROLLER, PAPER_CONTROLLER,
                            PAPER_GOVERNED_CONTROLLER, PARAMS_DIR, REAL_CONTROLLER)

__all__ = ["PARAMS_DIR", "DEFAULT_VEHICLE", "PAPER_CONTROLLER", "PAPER_GOVERNED_CONTROLLER",
           "DESIGN_CONTROLLER", "REAL_CONTROLLER", "add_model_arguments", "add_laps_argument",
           "add_entry_offset_argument", "load_model_params", "load_maneuver_arg",
           "add_gcs_arguments", "gcs_config", "add_signing_argument", "add_output_argument",
           "add_excitation_argument", "excitation_params", "add_vehicle_identity_arguments", "add_airborne_argument", "system_id",
           "add_planner_arguments", "planner_bounds", "Parser", "positive_float", "nonneg_float",
           "finite_float", "positive_int", "nonneg_int", "vehicle_url", "vehicle_url_help", "check_vehicle_link", "plot_file", "input_file",
           "output_file", "output_dir", "socket_path", "check_output_file", "check_output_dir",
           "DeprecatedAlias", "add_deprecated_alias"]


def add_model_arguments(p: argparse.ArgumentParser, controller: Path = REAL_CONTROLLER) -> None:
    """``--vehicle-params YAML`` and ``--controller YAML``. Every command that plans defaults to
    the controller ``fly`` and ``serve`` fly (``realistic.yaml``), so that ``plan`` prints the
    gains' margins the flight will have and ``simulate`` flies its gains."""
    p.add_argument("--vehicle-params", metavar="YAML", type=input_file, default=str(DEFAULT_VEHICLE),
                   help="vehicle parameter file (default: %(default)s)")
    p.add_argument("--controller", metavar="YAML", type=input_file, default=str(controller),
                   help="LQR weights (default: %(default)s)")


def add_laps_argument(p: argparse.ArgumentParser) -> None:
    """``--laps N`` (plan, simulate, fly, upload): the maneuver file's laps count, overridden."""
    p.add_argument("--laps", type=positive_int, default=None, metavar="N",
                   help="fly the maneuver's laps segment N times (default: as in the file)")


def add_entry_offset_argument(p: argparse.ArgumentParser, what: str) -> argparse.Action:
    """``--entry-offset DN DE DD`` (simulate, fly): start the maneuver off its entry, NED, m;
    ``what`` says what the command does with it. Returns the Action (for an alias)."""
    return p.add_argument("--entry-offset", nargs=3, type=finite_float, default=(0.0, 0.0, 0.0),
                          metavar=("DN", "DE", "DD"), help=f"{what} (default: 0 0 0)")


def add_planner_arguments(p: argparse.ArgumentParser) -> None:
    """--planner-memory-mib, --planner-cpu-s: what one upload may cost the planner worker."""
    from ..daemon.jobs.planner_pool import PlannerBounds
    d = PlannerBounds()
    p.add_argument("--planner-memory-mib", type=positive_int, default=d.memory_bytes >> 20, metavar="MIB",
                   help="memory one upload's planning may add to the planner worker; beyond it the "
                   "upload is rejected (default: %(default)s)")
    p.add_argument("--planner-cpu-s", type=positive_float, default=d.cpu_s, metavar="S",
                   help="CPU seconds one upload's planning may take; beyond them it is rejected "
                   "(default: %(default)s)")


def planner_bounds(args):
    """The :class:`~mavreg.daemon.jobs.planner_pool.PlannerBounds` of the options above."""
    import dataclasses

    from ..daemon.jobs.planner_pool import PlannerBounds
    return dataclasses.replace(PlannerBounds(), memory_bytes=args.planner_memory_mib << 20,
                               cpu_s=args.planner_cpu_s)


def load_model_params(args):
    from ..config.controller import load_controller
    from ..config.vehicle import load_vehicle
    return load_vehicle(args.vehicle_params), load_controller(args.controller)


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line: ``PROG: error: MESSAGE (see PROG --help)``."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def finite_float(text: str) -> float:
    """A finite number (no nan, no inf)."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def positive_float(text: str) -> float:
    """A finite number > 0 (a rate, a timeout, a force limit)."""
    v = finite_float(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return v


def nonneg_float(text: str) -> float:
    """A finite number >= 0 (a noise level)."""
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected a number >= 0, got {text!r}")
    return v


def _whole_number(text: str, least: int) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < least:
        raise argparse.ArgumentTypeError(f"must be at least {least}, got {n}")
    return n


def positive_int(text: str) -> int:
    """A whole number >= 1."""
    return _whole_number(text, 1)


def nonneg_int(text: str) -> int:
    """A whole number >= 0 (a seed)."""
    return _whole_number(text, 0)


def add_output_argument(p: argparse.ArgumentParser) -> None:
    """``--output rotors|rates`` (fly, serve): what the daemon commands."""
    p.add_argument("--output", choices=("rotors", "rates"), default=None,
                   help="what the daemon commands: 'rotors', rotor forces (SET_ACTUATOR_CONTROL_TARGET), "
                   "or 'rates', body rates and a normalized thrust (SET_ATTITUDE_TARGET), which stock "
                   "PX4 and ArduPilot autopilots take; needs the vehicle file's rate_interface: "
                   "section (docs/autopilots.md) (default: the vehicle file's output:, else rotors)")


def system_id(text: str) -> int:
    """A MAVLink system id, a whole number in 1..255."""
    n = _whole_number(text, 1)
    if n > 255:
        raise argparse.ArgumentTypeError(f"a MAVLink system id is at most 255, got {n}")
    return n


def add_vehicle_identity_arguments(p: argparse.ArgumentParser) -> None:
    """``--vehicle-system-id N`` and ``--dialect px4|ardupilot`` (fly, serve): which system on the
    link is the vehicle, and the mode layout of custom firmware (docs/autopilots.md, *Which
    dialect*)."""
    from ..config.vehicle import DIALECTS
    p.add_argument("--vehicle-system-id", type=system_id, default=None, metavar="N",
                   help="the vehicle's MAVLink system id, 1..255 (its MAV_SYS_ID or SYSID_THISMAV); the "
                   "daemon takes only its frames and addresses it, with the same id as its own "
                   "(default: on udpin: the system id of the first autopilot HEARTBEAT heard, never a "
                   "ground station's; on udpout: and the bundled emulator, 1, which the emulator is "
                   "then started with)")
    p.add_argument("--dialect", choices=DIALECTS, default=None,
                   help="the mode layout of custom firmware that announces MAV_AUTOPILOT_GENERIC (0): "
                   "'px4' (OFFBOARD, AUTO.LAND) or 'ardupilot' (GUIDED, LAND); its parameters are not "
                   "checked. Stock PX4 and ArduPilot are known from their HEARTBEAT and refuse a "
                   "contradicting choice (default: the vehicle file's dialect:, else PX4's in the rotors "
                   "output; the rates output refuses a GENERIC vehicle without a choice)")


def add_airborne_argument(p: argparse.ArgumentParser) -> None:
    """``--airborne land|fly`` (fly, serve): a vehicle found armed in the air (docs/safety.md)."""
    p.add_argument("--airborne", choices=("land", "fly"), default="land",   # phases.AIRBORNE_CHOICES (light import)
                   help="a vehicle found armed in the air (a daemon restarted mid-flight): it is taken "
                   "over where it is (set-points matching it stream before OFFBOARD is asked for; it is "
                   "never armed, disarmed or taken off), held, then 'land' (the queued maneuver is "
                   "dropped) or 'fly' (the queued maneuver, or with serve the next upload, from the "
                   "hold). A vehicle armed on the ground by another is refused and left armed "
                   "(default: %(default)s)")


def add_excitation_argument(p: argparse.ArgumentParser) -> None:
    """``--identify-excitation`` (fly, serve): the identification flight's rate doublets."""
    p.add_argument("--identify-excitation", action="store_true",
                   help="an identification flight: in the hold before the first maneuver, rate doublets on "
                   "roll, pitch and yaw (+-0.5, 0.5, 0.1 rad/s for 0.15, 0.3, 0.15 s, 0 for 0.2 s, 0.6 s to settle, 3 rounds: 12.6 s) "
                   "that pin the autopilot's rate loop for 'mavreg identify'; needs --output rates "
                   "(docs/identify.md) (default: off)")


def excitation_params(args, output: str):
    """The ExcitationParams of ``--identify-excitation`` (None: off); UsageError (one line)
    for an output with no rate loop to excite."""
    if not getattr(args, "identify_excitation", False):
        return None
    from ..daemon.flight.excitation import ExcitationParams, check_output
    from ..errors import UsageError
    try:
        check_output(ExcitationParams(), output)
    except ValueError as exc:
        raise UsageError(f"--identify-excitation: {exc}") from None
    return ExcitationParams()


def add_signing_argument(p: argparse.ArgumentParser, bundled_emulator: bool = False) -> None:
    """``--signing-key FILE`` (fly, serve): MAVLink 2 signing, :mod:`mavreg.transport.signing`."""
    also = "; the bundled emulator gets the same key" if bundled_emulator else ""
    p.add_argument("--signing-key", metavar="FILE", default=None,
                   help="MAVLink 2 signing: sign every message and accept only validly signed ones "
                   f"(FILE: 32 bytes as 64 hex characters or base64, mode 0600{also}; "
                   "docs/reliability.md) (default: signing off)")


def add_gcs_arguments(p: argparse.ArgumentParser) -> None:
    """``--gcs URL`` (repeatable) and ``--gcs-allow-commands`` (fly, serve)."""
    p.add_argument("--gcs", action="append", default=[], metavar="URL",
                   help="forward the flight live to a ground station (repeatable): udpout:HOST[:PORT] "
                   "sends to one that listens (QGroundControl, mavproxy.py --master udpin:...; "
                   "port 14550 if omitted), udpin:HOST[:PORT] waits for one to send first. "
                   "Read-only unless --gcs-allow-commands (docs/ground-station.md)")
    p.add_argument("--gcs-allow-commands", action="store_true",
                   help="pass the ground station's messages to the vehicle; while mavreg flies only "
                   "queries pass, land/RTL becomes mavreg's own landing, and mode, arming, set-points, "
                   "parameters and missions are refused (docs/ground-station.md)")


def gcs_config(args) -> dict:
    """The DaemonConfig fields of ``--gcs`` and ``--gcs-allow-commands``; UsageError on a bad URL."""
    from ..daemon.gcs.params import GcsParams, parse_gcs_url     # no MAVLink: checked before the imports
    from ..errors import UsageError
    for url in args.gcs:
        try:
            parse_gcs_url(url)
        except ValueError as exc:
            raise UsageError(str(exc)) from None
    if args.gcs_allow_commands and not args.gcs:
        raise UsageError("--gcs-allow-commands needs a --gcs URL")
    return {"gcs_urls": tuple(args.gcs), "gcs": GcsParams(allow_commands=args.gcs_allow_commands)}
PLOT_SUFFIXES = (".png", ".pdf", ".svg", ".jpg", ".jpeg")


def plot_file(text: str) -> str:
    """A figure to write: :func:`output_file` with a suffix matplotlib writes."""
    if Path(text).suffix.lower() not in PLOT_SUFFIXES:
        raise argparse.ArgumentTypeError(f"{text}: expected a file name ending in "
                                         f"{', '.join(PLOT_SUFFIXES)}")
    return output_file(text)


def input_file(text: str) -> str:
    """A path to a regular file this process can read (not a directory, not /dev/zero)."""
    p = Path(text)
    try:
        p.stat()
    except OSError as exc:
        raise argparse.ArgumentTypeError(f"{text}: {exc.strerror or exc}") from None
    if p.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a directory, not a file")
    if not p.is_file():
        raise argparse.ArgumentTypeError(f"{text}: not a regular file")
    if not os.access(p, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text}: permission denied (not readable)")
    return text


def _writable_dir(d: Path, what: str) -> str | None:
    """Why the directory ``d`` (or the nearest existing one above it) cannot take ``what``."""
    probe = d
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        return f"{probe} is not a directory"
    if probe != d and what == "file":
        return f"no such directory {d}"
    if not os.access(probe, os.W_OK | os.X_OK):
        return f"directory {probe} is not writable"
    return None


def check_output_file(text: str) -> str | None:
    """Why a file cannot be written at ``text`` (None: it can, as far as can be told)."""
    p = Path(text)
    if p.is_dir():
        return f"{text}: is a directory"
    if p.exists() and not os.access(p, os.W_OK):
        return f"{text}: permission denied (not writable)"
    why = _writable_dir(p.parent if str(p.parent) else Path("."), "file")
    return None if why is None else f"{text}: {why}"


def check_output_dir(text: str) -> str | None:
    """Why a directory cannot be created or written at ``text`` (None: it can)."""
    p = Path(text)
    if p.exists() and not p.is_dir():
        return f"{text}: exists and is not a directory"
    why = _writable_dir(p, "dir")
    return None if why is None else f"{text}: {why}"


def output_file(text: str) -> str:
    """A file to write (its directory exists and is writable); the argparse type."""
    why = check_output_file(text)
    if why is not None:
        raise argparse.ArgumentTypeError(why)
    return text


UNIX_PATH_MAX = 107
"""Longest Unix socket path (sun_path is 108 bytes on Linux, with the terminating NUL)."""


def socket_path(text: str) -> str:
    """A Unix socket to listen on: not a directory, short enough, in a directory that exists
    or can be created (the endpoint creates it, mode 0700)."""
    p = Path(text)
    if p.is_dir():
        raise argparse.ArgumentTypeError(f"{text}: is a directory")
    if len(os.fsencode(text)) > UNIX_PATH_MAX:
        raise argparse.ArgumentTypeError(f"{text}: a Unix socket path is at most {UNIX_PATH_MAX} bytes")
    why = check_output_dir(str(p.parent))
    if why is not None:
        raise argparse.ArgumentTypeError(why)
    return text


def output_dir(text: str) -> str:
    """A directory to write into (exists or can be created, writable); the argparse type."""
    why = check_output_dir(text)
    if why is not None:
        raise argparse.ArgumentTypeError(why)
    return text


def load_maneuver_arg(args):
    """The maneuver file ``args.maneuver``, with ``--laps`` applied.

    Commands load it before they import the planner (numba, scipy: most of a second), so
    that a rejected file answers at once.
    """
    from ..config.maneuver import load_maneuver
    from ..errors import UsageError
    spec = load_maneuver(args.maneuver)
    if args.laps is None:
        return spec
    try:
        return spec.with_laps(args.laps)
    except ValueError as exc:        # no laps segment, or a count out of range: the user's
        raise UsageError(f"--laps {args.laps}: {exc}") from None
