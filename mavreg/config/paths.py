"""Where the bundled parameter files are: the one place that knows.

The vehicle, controller and maneuver YAML files ship inside the package (``mavreg/params/``,
package data of the wheel; the repository's top-level ``params`` is a symbolic link to it,
for typing ``mavreg plan params/maneuvers/barrel_roll.yaml`` in a checkout). Everything that
needs a bundled file (the commands' defaults, the experiments, the emulator's default vehicle,
benchmarks and tests) asks here, so an installed wheel, an editable install and a plain
checkout on ``PYTHONPATH`` all find the same files.
"""
from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["params_dir", "vehicle_file", "controller_file", "maneuver_file", "maneuver_files",
           "PARAMS_DIR", "DEFAULT_VEHICLE", "PAPER_CONTROLLER", "PAPER_GOVERNED_CONTROLLER",
           "DESIGN_CONTROLLER", "REAL_CONTROLLER"]


def params_dir() -> Path:
    """The directory of the bundled parameter files (``vehicles/``, ``controller/``, ``maneuvers/``).

    Not checked here (importing must not fail on a broken install): a missing file is reported
    by the loader that reads it, in one line.
    """
    return Path(str(resources.files("mavreg") / "params"))


def vehicle_file(name: str) -> Path:
    """``params/vehicles/<name>.yaml``, e.g. ``vehicle_file("mk_quadro")``."""
    return params_dir() / "vehicles" / f"{name}.yaml"


def controller_file(name: str) -> Path:
    """``params/controller/<name>.yaml``, e.g. ``controller_file("realistic")``."""
    return params_dir() / "controller" / f"{name}.yaml"


def maneuver_file(name: str) -> Path:
    """``params/maneuvers/<name>.yaml``, e.g. ``maneuver_file("barrel_roll")``."""
    return params_dir() / "maneuvers" / f"{name}.yaml"


def maneuver_files() -> list[Path]:
    """Every maneuver of the bundled library, sorted by name."""
    return sorted((params_dir() / "maneuvers").glob("*.yaml"))


PARAMS_DIR = params_dir()
DEFAULT_VEHICLE = vehicle_file("mk_quadro")
PAPER_CONTROLLER = controller_file("paper_lqr")
"""Exactly the paper's design (roll-pitch-yaw attitude error, per-rotor clipping, no speed
governor): for reproductions."""
PAPER_GOVERNED_CONTROLLER = controller_file("paper_governed")
"""The paper's design with mavreg's speed governor and torques-first allocation: the
experiments where a gust holds the vehicle back or the rotors saturate."""
DESIGN_CONTROLLER = controller_file("design")
"""The paper's weights on the SO(3) attitude error, with the governor and torques-first
allocation: ideal rotors (the gallery's design-model column; ``--controller`` to use it)."""
REAL_CONTROLLER = controller_file("realistic")
"""Lag-aware gains, delay prediction, weights for estimator noise: the default of every command
(fly, serve, plan, simulate, warm-up) and of the library's :func:`mavreg.load_controller`, so
that what ``plan`` prints and ``simulate`` flies is what ``fly`` flies."""
