"""What went wrong in a flight: one record of a violated bound, one of the flight's outcome.

- :class:`BoundViolation`: a bound exceeded, where (phase, vehicle time, arc length) and by
  how much. The envelope monitor, the gap and link checks and the supervisor's refusals all
  say it with this record (it was three: the monitor's ``Violation``, the bound half of the
  flight's ``Failure``, and a failing ``GateVerdict`` once placed in the flight).
- :class:`Outcome`: why a flight failed: its first violated bound, with every action the
  supervisor took from then on (``action``). ``mavreg fly`` prints :meth:`Outcome.line` and
  keeps :meth:`Outcome.as_dict` in ``summary.json`` under ``failure`` (docs/safety.md).

A health-gate check's answer stays its own type
(:class:`mavreg.daemon.flight.gate.GateVerdict`): it may be a pass, and it is not yet placed in a
phase or a time; :meth:`~mavreg.daemon.flight.gate.GateVerdict.at` makes the violation of it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["BoundViolation", "Outcome"]


@dataclass(frozen=True)
class BoundViolation:
    """A bound exceeded: where, by how much (SI values; ``unit`` names the unit)."""

    bound: str
    phase: str
    t_s: float
    """The vehicle's time (NaN before its first sample)."""
    s_m: float
    """Arc length in the maneuver, NaN elsewhere."""
    value: float
    limit: float
    unit: str
    detail: str
    impact: bool = field(default=False, kw_only=True)
    """The vehicle has hit something: the motors must stop, whatever the phase."""

    def describe(self) -> str:
        """One line: bound, where, value against limit (angles in degrees), detail; the time
        and the amount are left out where unknown (NaN)."""
        scale, unit = (180.0 / math.pi, "deg") if self.unit == "rad" else (1.0, self.unit)
        where = self.phase + ("" if math.isnan(self.s_m) else f" at s={self.s_m:.2f} m")
        t = "" if math.isnan(self.t_s) else f", t={self.t_s:.3f} s"
        amount = ("" if math.isnan(self.value) else
                  f": {self.value * scale:.3g} {unit} (limit {self.limit * scale:.3g} {unit})")
        return f"{self.bound} in {where}{t}{amount}; {self.detail}"


@dataclass(frozen=True)
class Outcome(BoundViolation):
    """Why a flight failed: the first bound violated, where, by how much, and what was done
    (``action``: the actions in order, joined by ", then ")."""

    action: str = ""

    def as_dict(self) -> dict:
        def num(x):
            return None if isinstance(x, float) and not math.isfinite(x) else x
        return {"bound": self.bound, "phase": self.phase, "s_m": num(self.s_m), "t_s": num(self.t_s),
                "value": num(self.value), "limit": num(self.limit), "unit": self.unit,
                "detail": self.detail, "action": self.action}

    def line(self) -> str:
        """The cause in one line."""
        return f"{self.describe()}; action: {self.action}"

    @classmethod
    def of(cls, violation: BoundViolation, action: str = "") -> Outcome:
        """The outcome whose first violated bound is ``violation``."""
        v = violation
        return cls(v.bound, v.phase, v.t_s, v.s_m, v.value, v.limit, v.unit, v.detail, action,
                   impact=v.impact)
