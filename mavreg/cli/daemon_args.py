"""The options ``fly`` and ``serve`` share, and the one function that turns their parsed
arguments into the daemon's options (:class:`mavreg.daemon.jobs.assembly.DaemonOptions`).

Each shared option is defined here once (``--control-rate-hz``, ``--stale-timeout-s``,
``--vehicle-lockstep``, the vehicle's identity, ``--output``, signing, ground stations, the
planner's bounds, the parameter files); :func:`daemon_options` loads the vehicle and
controller files once, checks what can be checked before anything starts (one line each),
and builds the options by keyword. Nothing here imports MAVLink, numba or an event loop.
"""
from __future__ import annotations

from pathlib import Path

from ..config.defaults import CONTROL_RATE_HZ, STALE_TIMEOUT_S
from .common import (REAL_CONTROLLER, add_airborne_argument, add_excitation_argument, add_gcs_arguments,
                     add_model_arguments, add_output_argument, add_planner_arguments, add_signing_argument,
                     add_vehicle_identity_arguments, excitation_params, gcs_config, planner_bounds,
                     positive_float)
from .vehicle_link import check_vehicle_link

__all__ = ["OUT_HELP", "add_daemon_arguments", "daemon_options"]

OUT_HELP = "output directory"
"""The start of every ``--out DIR`` help (docs/cli.md: one word for the output directory)."""


def add_daemon_arguments(p, bundled_emulator: bool = False) -> None:
    """The options of the daemon ``fly`` and ``serve`` both start (``bundled_emulator``: fly's
    help also says what the bundled emulator does with them)."""
    started = "; the bundled emulator is started at it" if bundled_emulator else ""
    p.add_argument("--control-rate-hz", type=positive_float, default=CONTROL_RATE_HZ, metavar="HZ",
                   help=f"the vehicle's telemetry/control rate{started}; the regulator leads its "
                   "feedforward by half its period (default %(default)s)")
    p.add_argument("--stale-timeout-s", type=positive_float, default=STALE_TIMEOUT_S, metavar="S",
                   help="link lost: stop streaming for good when no complete state arrives for S "
                   "wall seconds; shorter pauses are ridden out in hover, a recovery starts after 0.1 s "
                   "in a maneuver (docs/safety.md) (default: %(default)s)")
    p.add_argument("--vehicle-lockstep", action="store_true",
                   help="the --vehicle is a lockstep simulator (it waits for each command): do not "
                   "fly telemetry gaps on the prediction (in real time the daemon does)")
    add_vehicle_identity_arguments(p)
    add_airborne_argument(p)
    add_output_argument(p)
    add_excitation_argument(p)
    add_signing_argument(p, bundled_emulator=bundled_emulator)
    add_gcs_arguments(p)
    add_planner_arguments(p)
    add_model_arguments(p, controller=REAL_CONTROLLER)


def daemon_options(args, progress, **job):
    """The :class:`~mavreg.daemon.jobs.assembly.DaemonOptions` of ``args`` (parsed by a parser
    with :func:`add_daemon_arguments`), with the command's own fields ``job`` (by keyword:
    ``fly``'s maneuvers, output directory, emulator; ``serve``'s flights, logs).

    The vehicle file is loaded once (``--output`` and ``--dialect`` applied), the controller
    file once; a bad key file, ``--gcs`` URL, vehicle file, serial port or
    ``--identify-excitation`` is a UsageError or ConfigError (one line) before anything starts.
    ``args.vehicle`` None: the bundled emulator (``job`` gives it)."""
    from ..config.controller import load_controller
    from ..config.vehicle import load_vehicle, with_dialect, with_output
    from ..daemon.jobs.assembly import DaemonOptions
    signing_key = None if args.signing_key is None else Path(args.signing_key)
    if signing_key is not None:
        from ..transport.signing import load_key
        load_key(signing_key)           # a bad key file: one line before anything starts
    gcs = gcs_config(args)
    vehicle = with_dialect(with_output(load_vehicle(args.vehicle_params), args.output), args.dialect)
    check_vehicle_link(args.vehicle, args.control_rate_hz, vehicle.output, signing_key is not None)
    return DaemonOptions(
        vehicle=vehicle, controller=load_controller(args.controller), vehicle_url=args.vehicle,
        excitation=excitation_params(args, vehicle.output), control_rate_hz=args.control_rate_hz,
        stale_timeout_s=args.stale_timeout_s, vehicle_lockstep=args.vehicle_lockstep,
        vehicle_system_id=args.vehicle_system_id, airborne=args.airborne, signing_key=signing_key,
        planner=planner_bounds(args), progress=progress, **gcs, **job)
