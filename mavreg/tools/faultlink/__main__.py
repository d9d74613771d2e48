"""``python -m mavreg.tools.faultlink``: a faulty UDP link between a daemon and a vehicle.

Example (10 % loss and 0-5 ms jitter both ways, a 0.5 s outage 30 s after the start)::

    python -m mavreg.tools.faultlink --listen 127.0.0.1:14600 --vehicle 127.0.0.1:14540 \\
        --both loss=0.1,jitter_s=0.005 --both outage=30:0.5 --seed 7
    mavreg fly maneuver.yaml --vehicle udpout:127.0.0.1:14600 ...

Prints the counters of each direction every ``--report-s`` seconds and on exit (Ctrl-C).
"""
from __future__ import annotations

import argparse
import asyncio
import dataclasses
import signal
import socket
import sys

from .model import SPEC_KEYS, parse_faults
from .proxy import start_proxy


def _addr(text: str, flag: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    try:
        if not sep:
            raise ValueError
        info = socket.getaddrinfo(host, int(port), socket.AF_INET, socket.SOCK_DGRAM)[0][4]
    except (ValueError, OSError):
        raise ValueError(f"{flag} {text[:60]!r}: expected HOST:PORT") from None
    return info[0], info[1]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m mavreg.tools.faultlink", description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog=f"fault keys: {', '.join(SPEC_KEYS)} (see docs/reliability.md)")
    p.add_argument("--listen", required=True, help="HOST:PORT the daemon sends to (port 0: any)")
    p.add_argument("--vehicle", required=True, help="HOST:PORT of the vehicle")
    for flag, what in (("--both", "both directions"), ("--up", "daemon -> vehicle"),
                       ("--down", "vehicle -> daemon")):
        p.add_argument(flag, action="append", default=[], metavar="SPEC",
                       help=f"faults of {what}: KEY=VALUE[,KEY=VALUE...] (repeatable)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--report-s", type=float, default=5.0)
    return p


def _line(name: str, counters) -> str:
    return f"{name}: " + " ".join(f"{k}={v}" for k, v in dataclasses.asdict(counters).items())


async def _run(args) -> None:
    listen, vehicle = _addr(args.listen, "--listen"), _addr(args.vehicle, "--vehicle")
    notices: list = []
    up = parse_faults(",".join(args.both + args.up), seed=args.seed, on_deprecated=notices.append)
    down = parse_faults(",".join(args.both + args.down), seed=args.seed, on_deprecated=notices.append)
    for notice in dict.fromkeys(notices):
        print(f"faultlink: warning: {notice}", file=sys.stderr, flush=True)
    proxy = await start_proxy(listen, vehicle, up, down)
    print(f"faultlink listening on {proxy.listen_addr[0]}:{proxy.listen_addr[1]} -> "
          f"{vehicle[0]}:{vehicle[1]}", flush=True)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    try:
        while not stop.is_set():
            try:
                await asyncio.wait_for(stop.wait(), max(args.report_s, 0.1))
            except asyncio.TimeoutError:
                print(_line("up", proxy.up.counters) + " | " + _line("down", proxy.down.counters), flush=True)
    finally:
        proxy.close()
        print(_line("up", proxy.up.counters) + " | " + _line("down", proxy.down.counters), flush=True)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        asyncio.run(_run(args))
    except ValueError as exc:
        print(f"faultlink: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
