"""The command-line options of the PX4-facing side (:mod:`firmware_sim.px4`)."""
from __future__ import annotations

import argparse

from .px4 import Px4Config, Px4Services

__all__ = ["add_px4_args", "px4_services", "parse_home"]


def parse_home(text: str) -> tuple[float, float, float]:
    """``LAT,LON,ALT`` (degrees, degrees, m AMSL) -> a tuple. Raises ValueError."""
    parts = text.split(",")
    if len(parts) != 3:
        raise ValueError(f"--home {text!r}: expected LAT,LON,ALT (degrees, degrees, m AMSL)")
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--home {text!r}: LAT, LON and ALT must be numbers") from None
    if not (-85.0 <= lat <= 85.0 and -180.0 <= lon <= 180.0 and -500.0 <= alt <= 10000.0):
        raise ValueError(f"--home {text!r}: LAT in -85..85, LON in -180..180, ALT in -500..10000 m")
    return lat, lon, alt


def _home_type(text: str):
    try:
        return parse_home(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_px4_args(p: argparse.ArgumentParser) -> None:
    """``--home`` (docs/firmware_sim.md, 'Talking to it like a PX4 vehicle')."""
    g = p.add_argument_group("PX4 vehicle", "what a ground station or MAVSDK sees (docs/firmware_sim.md)")
    g.add_argument("--home", type=_home_type, default=None, metavar="LAT,LON,ALT",
                   help="where the local NED origin is on earth, degrees and m AMSL (default "
                   "PX4 SITL's home, 47.397742,8.545594,488); GLOBAL_POSITION_INT and "
                   "HOME_POSITION are converted around it")


def px4_services(args) -> Px4Services:
    """The services of the parsed arguments."""
    home = getattr(args, "home", None)
    cfg = Px4Config() if home is None else Px4Config(*home)
    return Px4Services(cfg, args.rate_hz)
