"""``mavreg upload``: hand a maneuver to a running daemon and print the verdict."""
from __future__ import annotations

import json
from pathlib import Path

from ..errors import UsageError
from .common import add_laps_argument, input_file, positive_float

HELP = "upload a maneuver YAML to a running `mavreg serve` (or ask it to land / report)"
DESCRIPTION = """\
Send FILE to the daemon's control endpoint and print its verdict: "accepted" (the maneuver
was planned and is queued; it starts at the next safe point, a hold) or "rejected" with the
loader's or the feasibility check's reasons. Planning takes a few seconds; the daemon keeps
flying meanwhile. --land asks the daemon to land and disarm at the next safe point (the flight
ends; the next upload begins a new one);
--status prints its status as JSON. --laps N sends FILE with its laps segment flown N times
(the file is rewritten here, as YAML without its comments; the daemon plans what it gets).

Endpoint: --socket, else $MAVREG_SOCKET, else $XDG_RUNTIME_DIR/mavreg.sock, else
/tmp/mavreg-$UID/mavreg.sock.

Exit status: 0 accepted (or --land/--status answered); 1 rejected or refused by the
daemon; 2 bad arguments, unreadable file, or no daemon listening.
"""

_MAX_FILE_BYTES = 200 * 1024


def add_arguments(p):
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("maneuver", metavar="FILE", nargs="?", type=input_file, help="maneuver YAML (kind: maneuver)")
    g.add_argument("--land", action="store_true", help="ask the daemon to land and disarm")
    g.add_argument("--status", action="store_true", help="print the daemon's status as JSON")
    add_laps_argument(p)
    p.add_argument("--socket", metavar="PATH", default=None, help="control endpoint (default: see above)")
    p.add_argument("--timeout-s", type=positive_float, default=120.0, metavar="S",
                   help="wait this long for the verdict (default: %(default)s)")


def run(args) -> int:
    from ..daemon.jobs.endpoint import default_socket_path, request
    path = Path(args.socket) if args.socket else default_socket_path()
    if args.laps is not None and args.maneuver is None:
        raise UsageError("--laps needs a maneuver FILE")
    if args.land:
        req = {"op": "land"}
    elif args.status:
        req = {"op": "status"}
    else:
        f = Path(args.maneuver)
        if f.stat().st_size > _MAX_FILE_BYTES:
            raise UsageError(f"{f}: {f.stat().st_size} bytes; a maneuver file is at most {_MAX_FILE_BYTES}")
        try:
            text = f.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise UsageError(f"{f}: not UTF-8 text") from None
        if args.laps is not None:
            text = _with_laps(text, args.laps, str(f))
        req = {"op": "upload", "name": str(f), "yaml": text}
    try:
        resp = request(path, req, args.timeout_s)
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"no daemon answering on {path} ({exc.__class__.__name__}: {exc})") from None
    if args.status:
        print(json.dumps(resp.get("status", resp), indent=1))
        return 0 if resp.get("ok") else 1
    if args.land:
        print(resp.get("detail") or resp.get("reason") or f"error: {resp.get('error')}")
        return 0 if resp.get("ok") else 1
    if resp.get("ok"):
        print(f"accepted: {resp['detail']}")
        return 0
    if "error" in resp:   # the daemon failed to handle the request (see its log)
        print(f"error: {resp['error']}")
        return 1
    print(f"{resp.get('verdict', 'rejected')}: {resp.get('reason')}")
    return 1


def _with_laps(text: str, laps: int, source: str) -> str:
    """FILE's text with ``--laps`` applied; a file that cannot take it is refused here (exit 2)."""
    from ..config.maneuver import maneuver_text_with_laps
    try:
        return maneuver_text_with_laps(text, laps, source)
    except ValueError as exc:       # ConfigError too: the file is refused before it is sent
        raise UsageError(f"--laps {laps}: {exc}") from None
