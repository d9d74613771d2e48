"""Old spellings of command-line options, kept for one release: the one argparse action that
``mavreg`` (every subcommand) and ``firmware-sim`` share (docs/cli.md, *Old spellings*).

An old spelling is a hidden option that stores into the new option's destination and prints
one line on stderr, ``PROG: warning: OLD is deprecated and goes in the next release; use
NEW``. An old spelling in another unit (``--telemetry-delay-ms`` for ``--telemetry-delay-s``)
converts its value first, exactly in decimal (``scale="1e-3"``), so that ``--X-ms 20`` and
``--X-s 0.02`` give the same float and the same bounds check.

The module imports nothing but the standard library: the emulator stands for somebody else's
firmware and takes nothing of mavreg's command line (``mavreg.cli``); this neutral module is
the one piece of command-line plumbing both may import (pyproject's import contracts).
"""
from __future__ import annotations

import argparse
import decimal
import sys

__all__ = ["DeprecatedAlias", "add_deprecated_alias", "scaled_text"]


def scaled_text(text: str, scale: str) -> str:
    """``text`` (a number) times ``scale``, exactly, as text: ``("20", "1e-3") -> "0.020"``.

    The product is formed in decimal, so that ``float`` of the result is the double nearest
    to the number meant (``float("0.020") == 0.02``, which ``20 * 1e-3`` need not be). Text that
    is not a finite number is returned as it is, for the new option's type to refuse.
    """
    try:
        value = decimal.Decimal(text.strip())
    except decimal.InvalidOperation:
        return text
    if not value.is_finite():
        return text
    return str(value * decimal.Decimal(scale))


class DeprecatedAlias(argparse.Action):
    """A hidden old spelling of an option: stores into the new option's ``dest`` and prints
    one line ``PROG: warning: OLD is deprecated and goes in the next release; use NEW`` on
    stderr."""

    def __init__(self, option_strings, dest, new: str, **kwargs):
        self.new = new
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"{parser.prog}: warning: {option_string} is deprecated and goes in the next release; "
              f"use {self.new}", file=sys.stderr, flush=True)
        setattr(namespace, self.dest, values)


def _converted(convert, scale: str, unit: str):
    """The new option's type ``convert`` reading an old value in the old unit: the value is
    scaled (:func:`scaled_text`) first; a refusal names the value as it was typed."""
    def parse(text: str):
        scaled = scaled_text(text, scale)
        try:
            return convert(scaled)
        except argparse.ArgumentTypeError as exc:
            if scaled == text:
                raise
            raise argparse.ArgumentTypeError(f"{text} ({scaled} {unit}): {exc}") from None
    parse.__name__ = getattr(convert, "__name__", "value")
    return parse


def add_deprecated_alias(p, old: str, new: argparse.Action, *, scale: str | None = None,
                         unit: str = "") -> None:
    """Accept ``old`` as a hidden alias of the option ``new`` for one release.

    Parameters
    ----------
    p : argparse.ArgumentParser or argument group
        Where ``new`` was added.
    old : str
        The old spelling, e.g. ``"--rate-hz"``.
    new : argparse.Action
        What ``add_argument`` returned for the new spelling: the alias takes its
        destination, type, count, choices and metavar.
    scale : str, optional
        The old unit in the new one, as a decimal: ``"1e-3"`` for an old option in
        milliseconds of a new one in seconds. Each value is multiplied by it exactly before
        the new option's type reads it (and checks its bounds, in the new unit).
    unit : str
        The new option's unit, named in a refusal of a scaled value (``"s"``).
    """
    convert = new.type
    if scale is not None:
        if convert is None:
            raise ValueError(f"{old}: a converting alias needs a typed new option")
        convert = _converted(convert, scale, unit)
    p.add_argument(old, dest=new.dest, type=convert, nargs=new.nargs, choices=new.choices,
                   metavar=new.metavar, default=argparse.SUPPRESS, action=DeprecatedAlias,
                   new=new.option_strings[0], help=argparse.SUPPRESS)
