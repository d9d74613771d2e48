"""Options every planning command shares: the vehicle and controller files."""
from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["PARAMS_DIR", "add_model_arguments", "add_laps_argument", "load_model_params",
           "add_gcs_arguments", "gcs_config"]

PARAMS_DIR = Path(__file__).resolve().parents[2] / "params"
DEFAULT_VEHICLE = PARAMS_DIR / "vehicles" / "mk_quadro.yaml"
PAPER_CONTROLLER = PARAMS_DIR / "controller" / "paper_lqr.yaml"
"""Exactly the paper's design (roll-pitch-yaw attitude error, per-rotor clipping, no speed
governor): for reproductions."""
PAPER_GOVERNED_CONTROLLER = PARAMS_DIR / "controller" / "paper_governed.yaml"
"""The paper's design with mavreg's speed governor and torques-first allocation: the
experiments where a gust holds the vehicle back or the rotors saturate."""
DESIGN_CONTROLLER = PARAMS_DIR / "controller" / "design.yaml"
"""The paper's weights on the SO(3) attitude error: the default of the design-model commands
(plan, simulate)."""
REAL_CONTROLLER = PARAMS_DIR / "controller" / "realistic.yaml"
"""Lag-aware gains, delay prediction, weights for estimator noise: the default of the commands
that fly a vehicle (fly, serve)."""


def add_model_arguments(p: argparse.ArgumentParser, controller: Path = DESIGN_CONTROLLER) -> None:
    p.add_argument("--vehicle-params", metavar="YAML", default=str(DEFAULT_VEHICLE),
                   help="vehicle parameter file (default: %(default)s)")
    p.add_argument("--controller", metavar="YAML", default=str(controller),
                   help="LQR weights (default: %(default)s)")


def _laps(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {n}")
    return n


def add_laps_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument("--laps", type=_laps, default=None, metavar="N",
                   help="fly the maneuver's laps segment N times (default: as in the file)")


def load_model_params(args):
    from ..config.controller import load_controller
    from ..config.vehicle import load_vehicle
    return load_vehicle(args.vehicle_params), load_controller(args.controller)


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
    """The DaemonConfig fields of ``--gcs`` and ``--gcs-allow-commands``; ValueError on a bad URL."""
    from ..daemon.gcs import GcsParams, parse_gcs_url
    for url in args.gcs:
        parse_gcs_url(url)
    if args.gcs_allow_commands and not args.gcs:
        raise ValueError("--gcs-allow-commands needs a --gcs URL")
    return {"gcs_urls": tuple(args.gcs), "gcs": GcsParams(allow_commands=args.gcs_allow_commands)}
