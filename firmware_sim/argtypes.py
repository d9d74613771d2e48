"""The argparse types of ``firmware-sim``: a bad value is refused while the command line is
parsed, in one line (exit 2), before anything is built or run."""
from __future__ import annotations

import argparse
import math
import os

__all__ = ["_float_above", "_positive_float", "_nonneg_float", "_probability", "_positive_int", "_nonneg_int", "_unit_scale", "_sysid", "_checked", "_input_file", "_output_file"]


def _float_above(minimum: float, inclusive: bool):
    """An argparse type: a finite float > minimum (>= with ``inclusive``)."""
    op = ">=" if inclusive else ">"

    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not (math.isfinite(v) and (v >= minimum if inclusive else v > minimum)):
            raise argparse.ArgumentTypeError(f"expected a finite number {op} {minimum:g}, got {text!r}")
        return v
    return parse


_positive_float = _float_above(0.0, inclusive=False)
_nonneg_float = _float_above(0.0, inclusive=True)


def _probability(text: str) -> float:
    v = _nonneg_float(text)
    if v > 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1], got {text!r}")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected an integer > 0, got {text!r}")
    return v


def _nonneg_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return v


def _unit_scale(text: str) -> float:
    v = _positive_float(text)
    if v > 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {text!r}")
    return v


def _sysid(text: str) -> int:
    v = _positive_int(text)
    if v > 255:
        raise argparse.ArgumentTypeError(f"expected a MAVLink system id 1..255, got {text!r}")
    return v


def _checked(parse, what: str):
    """An argparse type from a parser of firmware_sim that raises ValueError on bad text."""
    def convert(text: str):
        try:
            parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return text
    convert.__name__ = what
    return convert


def _input_file(text: str) -> str:
    """A readable regular file (the vehicle YAML)."""
    if not os.path.isfile(text) or not os.access(text, os.R_OK):
        why = ("is a directory" if os.path.isdir(text) else "not a readable regular file"
               if os.path.exists(text) else "no such file")
        raise argparse.ArgumentTypeError(f"{text}: {why}")
    return text


def _output_file(text: str) -> str:
    """A file to write (--record): checked before the run, not after it."""
    parent = os.path.dirname(text) or "."
    if os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text}: is a directory")
    if not os.path.isdir(parent):
        raise argparse.ArgumentTypeError(f"{text}: no such directory {parent}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: directory {parent} is not writable")
    return text
