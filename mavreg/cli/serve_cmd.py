"""``mavreg serve``: the long-running daemon that flies uploaded maneuvers."""
from __future__ import annotations

import sys
from pathlib import Path

from ..config.defaults import CONTROL_RATE_HZ, STALE_TIMEOUT_S
from .common import (REAL_CONTROLLER, add_gcs_arguments, add_model_arguments, add_excitation_argument, add_output_argument,
                     add_planner_arguments,
                     add_signing_argument, add_vehicle_identity_arguments, add_airborne_argument, excitation_params,
                     gcs_config, output_file, planner_bounds, positive_float, positive_int, socket_path, vehicle_url,
                     vehicle_url_help, check_vehicle_link)

HELP = "run the offboard daemon: fly maneuvers uploaded on the control endpoint"
DESCRIPTION = """\
Connect to the vehicle over MAVLink 2 (heartbeat as MAV_TYPE_ONBOARD_CONTROLLER, component
191, same system id as the vehicle), then wait for maneuvers on the control endpoint, a
Unix domain socket of mode 0600. Default location: $MAVREG_SOCKET, else
$XDG_RUNTIME_DIR/mavreg.sock, else /tmp/mavreg-$UID/mavreg.sock.

A flight: the first accepted upload arms the vehicle, takes off to the hold point before its
entry and flies it; afterwards the daemon holds at the exit and flies later uploads from
there. Uploads are planned in a worker process (the control loop keeps its rate) and start
only at a safe point (hold); a rejected upload changes nothing. `mavreg upload FILE --laps N`
flies FILE's laps segment N times. `mavreg upload --land` lands and disarms: the flight ends.

Flight after flight: when a flight ends, its outcome is a line on stderr and in the endpoint's
status (`mavreg upload --status`), and the next upload begins a new flight, with no restart:
at once after a landing and disarm, and after a flight that ended otherwise (aborted: the
link lost, the vehicle taken out of OFFBOARD) once the vehicle reports itself disarmed, so a
vehicle its pilot or its failsafe flies is never taken back. --once stops after the first
flight instead. A vehicle refused as such (its autopilot, its parameters) stops the daemon.

SIGINT/SIGTERM: the first lands (when airborne) and then exits; a second one exits at once,
which stops the command stream so that the vehicle's own failsafe lands it.

Writes a .tlog of every MAVLink message (--tlog, default none) and the controller log
(--control-log, default none): one file per flight, numbered (flight.tlog: flight-0001.tlog,
...), of which the newest --keep-logs stay (with --once: the name as given).

Exit status: 0 stopped on request, or landed and disarmed (--once); 1 the last flight was
aborted (stale state, non-finite output, the vehicle left OFFBOARD) or the vehicle was
refused before take-off (a vehicle mavreg does not fly, a parameter, the link: the daemon
ends at once, the cause in one line); 2 bad arguments or files (--tlog, --control-log and
--socket are checked before the daemon starts), or another daemon serves on the socket.
"""


def add_arguments(p):
    p.add_argument("--vehicle", metavar="URL", type=vehicle_url, default="udpout:127.0.0.1:14540",
                   help=vehicle_url_help("%(default)s"))
    p.add_argument("--socket", metavar="PATH", type=socket_path, default=None,
                   help="control endpoint (default: $MAVREG_SOCKET, $XDG_RUNTIME_DIR/mavreg.sock "
                   "or /tmp/mavreg-$UID/mavreg.sock)")
    p.add_argument("--tlog", metavar="FILE", type=output_file, default=None, help="write a MAVLink .tlog "
                   "here (stamped with the vehicle's clock with --vehicle-lockstep, else the wall clock)")
    p.add_argument("--control-log", metavar="FILE.npz", type=output_file, default=None,
                   help="write the controller log (s, w, u, phase) here on exit")
    p.add_argument("--once", action="store_true",
                   help="stop after the first flight ends (default: fly flight after flight until stopped)")
    p.add_argument("--keep-logs", type=positive_int, default=20, metavar="N",
                   help="the newest N per-flight .tlog and controller logs stay on disk (default %(default)s)")
    p.add_argument("--control-rate-hz", type=positive_float, default=CONTROL_RATE_HZ, metavar="HZ",
                   help="the vehicle's telemetry/control rate; the regulator leads its "
                   "feedforward by half its period (default %(default)s)")
    p.add_argument("--stale-timeout-s", type=positive_float, default=STALE_TIMEOUT_S, metavar="S",
                   help="link lost: stop streaming for good when no complete state arrives for S "
                   "seconds; shorter pauses are ridden out in hover, a recovery starts after 0.1 s "
                   "in a maneuver (docs/safety.md) (default: %(default)s)")
    p.add_argument("--vehicle-lockstep", action="store_true",
                   help="the vehicle is a lockstep simulator (it waits for each command): do not "
                   "fly telemetry gaps on the prediction (in real time the daemon does)")
    add_vehicle_identity_arguments(p)
    add_airborne_argument(p)
    add_output_argument(p)
    add_excitation_argument(p)
    add_signing_argument(p)
    add_gcs_arguments(p)
    add_planner_arguments(p)
    add_model_arguments(p, controller=REAL_CONTROLLER)


def run(args) -> int:
    from ..progress import Progress
    progress = Progress()       # the daemon's clock starts with the command
    from ..config.controller import load_controller
    from ..config.vehicle import load_vehicle, with_dialect, with_output
    if args.signing_key is not None:
        from ..transport.signing import load_key
        load_key(args.signing_key)      # a bad key file: one line, and no other before it
    gcs = gcs_config(args)
    vehicle = with_dialect(with_output(load_vehicle(args.vehicle_params), args.output), args.dialect)
    check_vehicle_link(args.vehicle, args.control_rate_hz, vehicle.output, args.signing_key is not None)
    controller = load_controller(args.controller)
    excitation = excitation_params(args, vehicle.output)
    progress.line(f"serving {args.vehicle}")       # checked: the first line, before the daemon's imports
    import asyncio

    from ..control.controllers.hover import HoverParams
    from ..daemon.jobs.app import Daemon, DaemonConfig, regulator_factory
    from ..daemon.jobs.endpoint import default_socket_path
    from ..daemon.vehicle.peers import system_id_to_use
    from ..daemon.jobs.sdnotify import Notifier
    from ..daemon.flight.supervisor import Phase, SupervisorParams
    from ..transport.signing import Signing
    signing = Signing(args.signing_key, "mavreg") if args.signing_key is not None else None
    config = DaemonConfig(args.vehicle, Path(args.vehicle_params), Path(args.controller),
                          Path(args.socket) if args.socket else default_socket_path(),
                          Path(args.tlog) if args.tlog else None,
                          SupervisorParams(system_id_to_use(args.vehicle, args.vehicle_system_id),
                                           land_when_done=False, airborne=args.airborne,
                                           stale_timeout_s=args.stale_timeout_s,
                                           gap_fill=not args.vehicle_lockstep, lockstep=args.vehicle_lockstep,
                                           hover=HoverParams.from_controller(controller),
                                           excitation=excitation),
                          envelope=controller.envelope, controller=controller,
                          control_rate_hz=args.control_rate_hz, **gcs, planner=planner_bounds(args),
                          tlog_clock="vehicle" if args.vehicle_lockstep else "wall",
                          flights=1 if args.once else None,
                          control_log_path=Path(args.control_log) if args.control_log else None,
                          keep_control_log=args.control_log is not None, keep_logs=args.keep_logs)
    make_regulator = regulator_factory(vehicle, args.control_rate_hz, controller.disturbance,
                                      controller.allocation, controller.speed_governor, warm=False)
    notifier = Notifier()       # systemd's Type=notify (deploy/mavreg.service); nothing outside it
    progress.write = _with_status(progress.write, notifier)
    daemon = Daemon(config, vehicle, make_regulator, signing=signing, progress=progress, notifier=notifier)
    asyncio.run(daemon.run())
    failure = daemon.supervisor.failure
    if failure is not None and failure.phase == Phase.PREFLIGHT:      # refused before take-off
        print(f"mavreg serve: {failure.line()}", file=sys.stderr, flush=True)
        return 1
    return 1 if daemon.supervisor.phase == Phase.ABORTED else 0


def _with_status(write, notifier):
    """``write``, each line also systemd's STATUS (``systemctl status`` shows the start)."""
    if not notifier.enabled:
        return write

    def both(line: str) -> None:
        write(line)
        notifier.status(line.split("setup: ", 1)[-1])
    return both
