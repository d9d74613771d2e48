"""Wind: steady wind and gusts, as a wind velocity or an external force over a time window.

Syntax of one ``--wind`` item (repeatable, items add up)::

    velocity:VN,VE,VD              steady wind velocity (m/s, NED; the air moves this way)
    velocity:VN,VE,VD@T0:T1        gust: wind velocity added for T0 <= t < T1 (s, sim time)
    force:FN,FE,FD                 steady external force on the airframe (N, NED)
    force:FN,FE,FD@T0:T1           force gust over a window

A wind velocity acts only through the vehicle's linear drag (``emulator.linear_drag_xyz_n_s_per_m``);
with zero drag it has no effect (the CLI warns). A force acts directly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["WindItem", "Wind", "parse_wind"]

_ZERO = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class WindItem:
    """One wind component, active for ``start_s <= t < end_s``."""

    kind: str                      # "velocity" (m/s) or "force" (N)
    vector_ned: tuple[float, float, float]
    start_s: float = 0.0
    end_s: float = math.inf


def parse_wind(text: str) -> WindItem:
    """Parse one ``--wind`` item (see the module docstring).

    Raises
    ------
    ValueError
        With a one-line message naming the item.
    """
    kind, sep, rest = text.partition(":")
    if not sep or kind not in ("velocity", "force"):
        raise ValueError(f"--wind {text!r}: expected 'velocity:VN,VE,VD[@T0:T1]' or 'force:FN,FE,FD[@T0:T1]'")
    vec_text, at, window = rest.partition("@")
    try:
        vec = tuple(float(v) for v in vec_text.split(","))
        if at:
            t0_text, colon, t1_text = window.partition(":")
            if not colon:
                raise ValueError
            t0, t1 = float(t0_text), float(t1_text)
        else:
            t0, t1 = 0.0, math.inf
    except ValueError:
        raise ValueError(f"--wind {text!r}: expected three numbers, optionally followed by @T0:T1") from None
    if len(vec) != 3 or not all(math.isfinite(v) for v in vec):
        raise ValueError(f"--wind {text!r}: expected three finite numbers")
    if not (0.0 <= t0 < t1):
        raise ValueError(f"--wind {text!r}: window needs 0 <= T0 < T1")
    return WindItem(kind, vec, t0, t1)


class Wind:
    """Sum of wind items, evaluated at a simulation time."""

    def __init__(self, items=()):
        self.items = tuple(items)
        self.has_velocity = any(i.kind == "velocity" for i in self.items)

    def at(self, t_s: float):
        """``(wind_velocity_ned, external_force_ned)`` at ``t_s``, each a 3-tuple."""
        if not self.items:
            return _ZERO, _ZERO
        w = [0.0, 0.0, 0.0]
        f = [0.0, 0.0, 0.0]
        for it in self.items:
            if it.start_s <= t_s < it.end_s:
                acc = w if it.kind == "velocity" else f
                for i in range(3):
                    acc[i] += it.vector_ned[i]
        return tuple(w), tuple(f)
