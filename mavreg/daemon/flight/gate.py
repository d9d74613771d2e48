"""The health gate: a maneuver starts only from a hold that shows the vehicle is fit for it.

Sans-I/O. The supervisor feeds it the hold's samples once the move to the hold point has
ended (:meth:`HealthGate.observe`), and asks :meth:`HealthGate.evaluate` before ``run_in``.
Over the last ``GateParams.window_s`` of the hold it requires, in this order (causes
before symptoms, so the reason names what is wrong):

- the plan inside the envelope from this take-off point (altitude floor, geofence);
- the mean collective command within ``max_thrust_ratio_error`` of the design weight (the
  plan's feasibility was checked on the design mass);
- rotor commands that do not clip, and do not chatter (high-pass SD of each rotor,
  ``sqrt(mean(diff(f)^2) / 2)``, which is the SD of white noise and ~0 for smooth commands);
- tracking: largest distance from the hold point and largest attitude error within bounds;
- the link's delay and jitter within bounds, when known (unknown does not block);
- the link's *unmodelled* delay (:func:`unmodelled_delay_s`) at most half the delay margin of
  the loops about to fly (the maneuver's and the hover's, :mod:`mavreg.maneuver.plan_margins`),
  when both are known.

A failing check is a :class:`GateVerdict` with the bound, the value and the limit; once the
supervisor acts on it, it becomes a :class:`~mavreg.daemon.flight.records.BoundViolation`
(:meth:`GateVerdict.at`).
"""
from __future__ import annotations

import collections
import math
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ...config.envelope import EnvelopeParams
from ...config.vehicle import G
from .records import BoundViolation

__all__ = ["GateVerdict", "HealthGate", "NominalPoints", "nominal_points", "plan_outside_envelope", "MarginCheck",
           "delay_margin_of", "unmodelled_delay_s", "JITTER_SIGMAS", "sampling_verdict"]

JITTER_SIGMAS = 3.0
"""A predicted delay is the median of the last replies: each sample's own delay is within this
many jitter SDs of it."""


@dataclass(frozen=True)
class GateVerdict:
    """A check's answer before a maneuver (or a take-off): a pass (``ok``), or the bound that
    fails, its value and limit. Not yet a :class:`~mavreg.daemon.flight.records.BoundViolation`: it
    has no phase or time until the supervisor refuses on it (:meth:`at`)."""

    ok: bool
    bound: str = ""
    value: float = math.nan
    limit: float = math.nan
    unit: str = ""
    detail: str = ""

    def at(self, phase: str, t_s: float) -> BoundViolation:
        """The violation this failing verdict is, in ``phase`` at vehicle time ``t_s``."""
        return BoundViolation(self.bound, phase, t_s, math.nan, self.value, self.limit, self.unit, self.detail)


PASS = GateVerdict(True)


class NominalPoints(NamedTuple):
    """Points of a plan's nominal path (:func:`nominal_points`)."""

    s_m: np.ndarray
    """Their arc lengths."""
    position_ned_m: np.ndarray
    """Their positions, one row each."""


def nominal_points(plan, n: int = 400) -> NominalPoints:
    """``n`` points of the plan's nominal path (computed once per upload)."""
    s = np.linspace(0.0, plan.length_m, n)
    return NominalPoints(s, np.array([np.asarray(plan.nominal_state(si), dtype=float)[:3] for si in s]))


def plan_outside_envelope(points, origin_m, envelope: EnvelopeParams) -> GateVerdict | None:
    """A failing verdict when the nominal path ``points`` (from :func:`nominal_points`) leaves
    the envelope seen from the take-off point ``origin_m`` (floor, geofence), else None."""
    s, pts = points
    alt = origin_m[2] - pts[:, 2]
    if alt.min() < envelope.min_altitude_m:
        i = int(np.argmin(alt))
        return GateVerdict(False, "gate_plan_floor", float(alt[i]), envelope.min_altitude_m, "m",
                           f"the plan goes down to {alt[i]:.2f} m above the take-off point (s={s[i]:.2f} m)")
    if alt.max() > envelope.geofence_ceiling_m:
        return GateVerdict(False, "gate_plan_geofence", float(alt.max()), envelope.geofence_ceiling_m, "m",
                           "the plan climbs above the geofence ceiling")
    for axis, name in ((0, "north"), (1, "east")):
        d = float(np.abs(pts[:, axis] - origin_m[axis]).max())
        if d > envelope.geofence_half_width_m[axis]:
            return GateVerdict(False, "gate_plan_geofence", d, envelope.geofence_half_width_m[axis], "m",
                               f"the plan leaves the geofence box ({name})")
    return None


MAX_LAG_LOOP_FACTOR = 1.5
"""The largest :func:`~mavreg.control.actuator.lag_loop_factor` flown: measured on ArduCopter
at 200 Hz, 2.1 oscillated at maneuver start, 1.1 and 0.6 flew."""


def sampling_verdict(plan, regulator) -> GateVerdict | None:
    """Refuse gains that oscillate between commands at this control rate (the regulator's
    :attr:`~mavreg.control.regulator.ManeuverRegulator.lag_loop_factor` above
    :data:`MAX_LAG_LOOP_FACTOR`)."""
    factor = float(getattr(regulator, "lag_loop_factor", 0.0))
    if factor <= MAX_LAG_LOOP_FACTOR:
        return None
    tau = plan.rotor_time_constant_s
    return GateVerdict(False, "gate_control_period", factor, MAX_LAG_LOOP_FACTOR, "",
                       f"the design's rotor lag {tau * 1e3:.0f} ms is too short for the control period: its "
                       "feedback on the achieved wrench would answer most of each command one period later "
                       "and oscillate; raise the telemetry rate, or design on a longer rotor_time_constant_s "
                       "or smaller q_wrench (docs/autopilots.md)")


def delay_margin_of(plan) -> tuple[float, str] | None:
    """(the least delay margin, which loop) of a plan's maneuver and hover
    (:class:`~mavreg.maneuver.plan_margins.PlanMargins`), or None where not computed."""
    m = getattr(plan, "margins", None)
    if m is None:
        return None
    man = m.maneuver.delay_margin_s if m.maneuver is not None else math.nan
    hover = m.hover.delay_margin_s
    man, hover = (x if math.isfinite(x) else math.inf for x in (man, hover))
    return (man, f"maneuver {plan.name!r}") if man <= hover else (hover, "hover")


class MarginCheck(NamedTuple):
    """What the gate holds the link's unmodelled delay to (:meth:`HealthGate.link_verdict`)."""

    delay_margin_s: float
    loop: str
    """Which loop the margin is of (``maneuver 'name'`` or ``hover``)."""
    predicted_s: float | None
    """The link delay the prediction covers; None: no prediction."""
    period_s: float = 0.0
    """The control period: TIMESYNC reads one more than the delay the commands act with."""


def unmodelled_delay_s(delay_s: float, jitter_s: float, predicted_s: float | None,
                       period_s: float = 0.0) -> float:
    """The part of the measured sample-to-actuation delay ``delay_s`` the controller does not
    model. Without prediction (``predicted_s`` None) all of it, less the control period
    ``period_s`` that TIMESYNC reads beyond the commands' effective delay (docs/identify.md:
    2.0 ms on the ideal lockstep world, whose commands act at once). With prediction across
    ``predicted_s``, the difference (a horizon capped, or a configured delay that is not the
    measured one) plus ``JITTER_SIGMAS`` times the jitter ``jitter_s`` (the prediction uses
    the median)."""
    if predicted_s is None:
        return max(float(delay_s) - float(period_s), 0.0)
    return abs(float(delay_s) - float(predicted_s)) + JITTER_SIGMAS * float(jitter_s)


class HealthGate:
    """Judges the last ``window_s`` of a hold.

    Parameters
    ----------
    envelope : EnvelopeParams
    mass_kg, max_rotor_thrust_n : float
        The design weight and what counts as a clipped command.
    link_health : callable or None
        ``() -> (delay_s, jitter_s)`` or None when unknown.
    """

    def __init__(self, envelope: EnvelopeParams, mass_kg: float, max_rotor_thrust_n: float,
                 link_health: Callable[[], tuple[float, float] | None] | None = None):
        self.params = envelope.gate
        self.weight_n = float(mass_kg) * G
        self.fmax = float(max_rotor_thrust_n)
        self.link_health = link_health
        self._rows: collections.deque = collections.deque()   # (t, pos err, att err, f1..f4)

    def reset(self) -> None:
        self._rows.clear()

    def observe(self, t_s: float, position_error_m: float, attitude_error_rad: float, demand_n) -> None:
        """One hold sample: errors from the hold reference, rotor forces asked (unclipped)."""
        self._rows.append((t_s, position_error_m, attitude_error_rad, *(float(f) for f in demand_n)))
        while self._rows and t_s - self._rows[0][0] > self.params.window_s + 1e-9:
            self._rows.popleft()

    def ready(self) -> bool:
        """Whether a full window has been seen."""
        return len(self._rows) > 2 and self._rows[-1][0] - self._rows[0][0] >= 0.9 * self.params.window_s

    def link_verdict(self, margin: MarginCheck | None = None) -> GateVerdict | None:
        """The link's failing check (delay, then jitter, then the delay margin), or None when it
        passes or is unknown. Also asked before take-off: a vehicle whose link the controller
        cannot fly over does not leave the ground.

        ``margin``: the delay margin to hold the unmodelled delay (:func:`unmodelled_delay_s`)
        to, at most half of it; None: not checked."""
        g = self.params
        link = self.link_health() if self.link_health is not None else None
        if link is None:
            return None
        delay, jitter = link
        if delay > g.max_link_delay_s:
            return GateVerdict(False, "gate_link_delay", float(delay), g.max_link_delay_s, "s",
                               "link delay beyond what the controller tolerates")
        if jitter > g.max_link_jitter_s:
            return GateVerdict(False, "gate_link_jitter", float(jitter), g.max_link_jitter_s, "s",
                               "link jitter beyond what the controller tolerates")
        if margin is None or not math.isfinite(margin[0]):
            return None
        tau_s, what, predicted_s, period_s = margin
        late = unmodelled_delay_s(delay, jitter, predicted_s, period_s)
        if late > tau_s / 2:
            how = (f"of {delay * 1e3:.1f} ms measured, not predicted" if predicted_s is None else
                   f"of {delay * 1e3:.1f} ms measured, {predicted_s * 1e3:.1f} ms predicted, jitter included")
            return GateVerdict(False, "gate_delay_margin", late, tau_s / 2, "s",
                               f"unmodelled link delay {late * 1e3:.1f} ms ({how}) is more than half the "
                               f"{what}'s delay margin {tau_s * 1e3:.1f} ms")
        return None

    def evaluate(self, margin: MarginCheck | None = None) -> GateVerdict:
        """The first failing check over the window, or a pass (call when :meth:`ready`);
        ``margin`` as :meth:`link_verdict`."""
        g = self.params
        rows = np.array(self._rows)
        pos, att, f = rows[:, 1], rows[:, 2], rows[:, 3:7]
        ratio = float(f.sum(axis=1).mean()) / self.weight_n
        if abs(ratio - 1.0) > g.max_thrust_ratio_error:
            return GateVerdict(False, "gate_thrust", ratio, 1.0 + math.copysign(g.max_thrust_ratio_error, ratio - 1.0),
                               "ratio", f"the hold needs {ratio:.2f} x the design hover thrust: the vehicle's "
                               "mass or rotors differ from the design model")
        clipped = np.any((f < -1e-9) | (f > self.fmax + 1e-9), axis=1)
        if clipped.any():
            return GateVerdict(False, "gate_saturation", float(clipped.mean()), 0.0, "share",
                               "rotor commands clipped during the hold")
        hp = np.sqrt(np.mean(np.diff(f, axis=0) ** 2, axis=0) / 2.0)
        if hp.max() > g.max_rotor_hp_sd_n:
            i = int(np.argmax(hp))
            return GateVerdict(False, "gate_rotor_chatter", float(hp[i]), g.max_rotor_hp_sd_n, "N",
                               f"rotor {i + 1} command chatters (high-pass SD)")
        if pos.max() > g.max_position_error_m:
            return GateVerdict(False, "gate_position", float(pos.max()), g.max_position_error_m, "m",
                               "the hold does not hold its point")
        if att.max() > g.max_attitude_error_rad:
            return GateVerdict(False, "gate_attitude", float(att.max()), g.max_attitude_error_rad, "rad",
                               "the hold is not level")
        link = self.link_verdict(margin)
        if link is not None:
            return link
        return PASS
