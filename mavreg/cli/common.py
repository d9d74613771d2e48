"""Options every planning command shares: the vehicle and controller files."""
from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ["PARAMS_DIR", "add_model_arguments", "add_laps_argument", "load_model_params", "load_maneuver_arg"]

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


def load_maneuver_arg(args):
    """The maneuver file ``args.maneuver``, with ``--laps`` applied.

    Commands load it before they import the planner (numba, scipy: most of a second), so
    that a rejected file answers at once.
    """
    from ..config.maneuver import load_maneuver
    spec = load_maneuver(args.maneuver)
    return spec if args.laps is None else spec.with_laps(args.laps)
