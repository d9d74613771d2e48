"""The ``mavreg`` command line: one module per subcommand.

Each subcommand module defines ``HELP`` (one line), ``DESCRIPTION`` (the ``--help`` text),
``add_arguments(parser)`` and ``run(args) -> int``. User mistakes (``ValueError`` subclasses
from the loader and the planner) print one line and exit 2, never a traceback; a closed
pipe or a Ctrl-C neither (:mod:`mavreg.cli.guard`).
"""
from __future__ import annotations

import argparse
import importlib
import sys

from .guard import run_guarded

__all__ = ["main", "build_parser"]

SUBCOMMANDS = {
    "plan": "mavreg.cli.plan_cmd",
    "simulate": "mavreg.cli.simulate_cmd",
    "fly": "mavreg.cli.fly_cmd",
    "serve": "mavreg.cli.serve_cmd",
    "upload": "mavreg.cli.upload_cmd",
    "identify": "mavreg.cli.identify_cmd",
    "experiment": "mavreg.cli.experiment_cmd",
}

EXIT_USAGE = 2


def build_parser() -> tuple[argparse.ArgumentParser, dict]:
    parser = argparse.ArgumentParser(
        prog="mavreg",
        description="Maneuver-regulation offboard flight control for aggressive quadrotor "
        "maneuvers over MAVLink (Spedicato et al.). Plan a YAML maneuver, simulate it on the "
        "design model, or fly it on a vehicle or on the bundled firmware_sim emulator.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    modules = {}
    for name, modname in SUBCOMMANDS.items():
        mod = importlib.import_module(modname)
        p = sub.add_parser(name, help=mod.HELP, description=mod.DESCRIPTION,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        mod.add_arguments(p)
        modules[name] = mod
    return parser, modules


def _main(argv: list[str] | None) -> int:
    parser, modules = build_parser()
    args = parser.parse_args(argv)
    args.command_line = ["mavreg", *(sys.argv[1:] if argv is None else argv)]   # for provenance
    try:
        return int(modules[args.command].run(args) or 0)
    except ValueError as exc:  # ConfigError, ManeuverError: the user's input is at fault
        print(f"mavreg {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; a closed pipe exits 141 and a Ctrl-C 130, without a traceback."""
    return run_guarded("mavreg", lambda: _main(argv))


if __name__ == "__main__":
    sys.exit(main())
