"""The argparse types of ``firmware-sim``: a bad value is refused while the command line is
parsed, in one line (exit 2), before anything is built or run."""
from __future__ import annotations

import argparse
import math
import os

# The old spellings (docs/cli.md) are one action shared with mavreg's command line, in a
# module of the standard library only (pyproject's contract for firmware_sim allows it).
from mavreg.deprecated_options import add_deprecated_alias

__all__ = ["float_above", "float_within", "positive_float", "nonneg_float", "probability",
           "positive_int", "nonneg_int", "unit_scale", "sysid", "checked", "input_file",
           "output_file", "add_deprecated_alias"]


def float_above(minimum: float, inclusive: bool):
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


def float_within(low: float, high: float, unit: str):
    """An argparse type: a finite float in [low, high], ``unit`` named in the refusal."""
    def parse(text: str) -> float:
        v = float_above(low, inclusive=True)(text)
        if v > high:
            raise argparse.ArgumentTypeError(f"expected a number in [{low:g}, {high:g}] {unit}, got {text!r}")
        return v
    return parse


positive_float = float_above(0.0, inclusive=False)
nonneg_float = float_above(0.0, inclusive=True)


def probability(text: str) -> float:
    v = nonneg_float(text)
    if v > 1.0:
        raise argparse.ArgumentTypeError(f"expected a probability in [0, 1], got {text!r}")
    return v


def positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"expected an integer > 0, got {text!r}")
    return v


def nonneg_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return v


def unit_scale(text: str) -> float:
    v = positive_float(text)
    if v > 1.0:
        raise argparse.ArgumentTypeError(f"expected a number in (0, 1], got {text!r}")
    return v


def sysid(text: str) -> int:
    v = positive_int(text)
    if v > 255:
        raise argparse.ArgumentTypeError(f"expected a MAVLink system id 1..255, got {text!r}")
    return v


def checked(parse, what: str):
    """An argparse type from a parser of firmware_sim that raises ValueError on bad text."""
    def convert(text: str):
        try:
            parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return text
    convert.__name__ = what
    return convert


def input_file(text: str) -> str:
    """A readable regular file (the vehicle YAML)."""
    if not os.path.isfile(text) or not os.access(text, os.R_OK):
        why = ("is a directory" if os.path.isdir(text) else "not a readable regular file"
               if os.path.exists(text) else "no such file")
        raise argparse.ArgumentTypeError(f"{text}: {why}")
    return text


def output_file(text: str) -> str:
    """A file to write (--record): checked before the run, not after it."""
    parent = os.path.dirname(text) or "."
    if os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text}: is a directory")
    if not os.path.isdir(parent):
        raise argparse.ArgumentTypeError(f"{text}: no such directory {parent}")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text}: directory {parent} is not writable")
    return text
