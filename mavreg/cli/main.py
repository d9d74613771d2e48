"""The ``mavreg`` command line: one module per subcommand.

Each subcommand module defines ``HELP`` (one line), ``DESCRIPTION`` (the ``--help`` text),
``add_arguments(parser)`` and ``run(args) -> int``. The exit statuses are
:mod:`mavreg.errors`'s, the same for every command (each ``--help`` ends with them):
an anticipated error (:func:`mavreg.errors.exit_status_of`: a bad option or file is 2, a
maneuver that cannot be flown 1) prints one line ``mavreg CMD: error: ...``; any other
exception is a bug: its traceback, a line asking to report it, and exit 70. A closed pipe
(141) or a Ctrl-C (130) print neither (:mod:`mavreg.cli.guard`).
"""
from __future__ import annotations

import argparse
import importlib
import sys
import traceback

from ..errors import EXIT_BUG, EXIT_STATUS_TEXT, EXIT_USAGE, exit_status_of, one_line
from .common import Parser
from .guard import run_guarded

__all__ = ["main", "build_parser", "run_command", "EXIT_USAGE", "EXIT_BUG"]

SUBCOMMANDS = {
    "plan": "mavreg.cli.plan_cmd",
    "simulate": "mavreg.cli.simulate_cmd",
    "fly": "mavreg.cli.fly_cmd",
    "serve": "mavreg.cli.serve_cmd",
    "upload": "mavreg.cli.upload_cmd",
    "identify": "mavreg.cli.identify_cmd",
    "experiment": "mavreg.cli.experiment_cmd",
    "warm-up": "mavreg.cli.warm_up_cmd",
}

BUG_REPORT = "this is a bug in mavreg: please report it with the command line and the traceback above"


def build_parser() -> tuple[argparse.ArgumentParser, dict]:
    parser = Parser(
        prog="mavreg",
        description="Maneuver-regulation offboard flight control for aggressive quadrotor "
        "maneuvers over MAVLink (Spedicato et al.). Plan a YAML maneuver, simulate it on the "
        "design model, or fly it on a vehicle or on the bundled firmware_sim emulator.",
        epilog=EXIT_STATUS_TEXT, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    modules = {}
    for name, modname in SUBCOMMANDS.items():
        mod = importlib.import_module(modname)
        p = sub.add_parser(name, help=mod.HELP, description=mod.DESCRIPTION, epilog=EXIT_STATUS_TEXT,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        modules[name] = mod
    return parser, modules


def run_command(prog: str, body) -> int:
    """``body()``'s status; an anticipated error is one line on stderr and its status, any
    other exception a traceback, :data:`BUG_REPORT` and :data:`~mavreg.errors.EXIT_BUG`.

    ``KeyboardInterrupt`` and ``BrokenPipeError`` pass through to :mod:`.guard`.
    """
    try:
        return int(body() or 0)
    except (KeyboardInterrupt, BrokenPipeError):
        raise
    except Exception as exc:
        status = exit_status_of(exc)
        if status is None:
            traceback.print_exc()
            print(f"{prog}: {BUG_REPORT} (exit {EXIT_BUG})", file=sys.stderr, flush=True)
            return EXIT_BUG
        print(f"{prog}: error: {one_line(exc)}", file=sys.stderr, flush=True)
        return status


def _main(argv: list[str] | None) -> int:
    parser, modules = build_parser()
    args = parser.parse_args(argv)
    args.command_line = ["mavreg", *(sys.argv[1:] if argv is None else argv)]   # for provenance
    return run_command(f"mavreg {args.command}", lambda: modules[args.command].run(args))


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; a closed pipe exits 141 and a Ctrl-C 130, without a traceback."""
    return run_guarded("mavreg", lambda: _main(argv))


if __name__ == "__main__":
    sys.exit(main())
