"""``mavreg serve``: the long-running daemon that flies uploaded maneuvers."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .common import DeprecatedAlias, output_dir, output_file, positive_int, socket_path, vehicle_url, vehicle_url_help
from .daemon_args import OUT_HELP, add_daemon_arguments, daemon_options

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

With --out DIR (the output directory, as fly's), writes into DIR a .tlog of every MAVLink
message and the controller log, one of each per flight, numbered (flight-0001.tlog,
control-0001.npz, ...), of which the newest --keep-logs stay (with --once: flight.tlog and
control.npz); without it, neither. The old --tlog FILE and --control-log FILE.npz still work
for one release (a warning names --out; a device such as /dev/null is written as given).

Exit status: 0 stopped on request, or landed and disarmed (--once); 1 the last flight was
aborted (stale state, non-finite output, the vehicle left OFFBOARD) or the vehicle was
refused before take-off (a vehicle mavreg does not fly, a parameter, the link: the daemon
ends at once, the cause in one line); 2 bad arguments or files (--out and --socket are
checked before the daemon starts), or another daemon serves on the socket.
"""


def add_arguments(p):
    p.add_argument("--vehicle", metavar="URL", type=vehicle_url, default="udpout:127.0.0.1:14540",
                   help=vehicle_url_help("%(default)s"))
    p.add_argument("--socket", metavar="PATH", type=socket_path, default=None,
                   help="control endpoint (default: $MAVREG_SOCKET, $XDG_RUNTIME_DIR/mavreg.sock "
                   "or /tmp/mavreg-$UID/mavreg.sock)")
    p.add_argument("--out", metavar="DIR", type=output_dir, default=None,
                   help=f"{OUT_HELP}: each flight's flight-NNNN.tlog (stamped with the vehicle's clock "
                   "with --vehicle-lockstep, else the wall clock) and control-NNNN.npz (s, w, u, phase), "
                   "the newest --keep-logs of each (default: no logs)")
    for old, what in (("--tlog", "FILE"), ("--control-log", "FILE.npz")):
        p.add_argument(old, metavar=what, type=output_file, default=None, action=DeprecatedAlias,
                       new="--out DIR", help=argparse.SUPPRESS)
    p.add_argument("--once", action="store_true",
                   help="stop after the first flight ends (default: fly flight after flight until stopped)")
    p.add_argument("--keep-logs", type=positive_int, default=20, metavar="N",
                   help="the newest N per-flight .tlog and controller logs stay in --out (default %(default)s)")
    add_daemon_arguments(p)


def run(args) -> int:
    from ..progress import Progress
    progress = Progress()       # the daemon's clock starts with the command
    from ..daemon.jobs.endpoint import default_socket_path
    opts = daemon_options(args, progress, out_dir=Path(args.out) if args.out else None,
                          tlog_file=Path(args.tlog) if args.tlog else None,
                          control_log_file=Path(args.control_log) if args.control_log else None,
                          keep_logs=args.keep_logs, socket_path=Path(args.socket) if args.socket else default_socket_path(),
                          flights=1 if args.once else None, land_when_done=False, systemd=True)
    progress.line(f"serving {args.vehicle}")       # checked: the first line, before the daemon's imports
    import asyncio

    from ..daemon.jobs.assembly import assemble
    from ..daemon.flight.supervisor import Phase
    daemon = assemble(opts)
    asyncio.run(daemon.run())
    failure = daemon.supervisor.failure
    if failure is not None and failure.phase == Phase.PREFLIGHT:      # refused before take-off
        print(f"mavreg serve: {failure.line()}", file=sys.stderr, flush=True)
        return 1
    return 1 if daemon.supervisor.phase == Phase.ABORTED else 0
