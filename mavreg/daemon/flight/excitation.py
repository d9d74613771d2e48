"""The identification flight's excitation: rate pulses (mirrored doublets) on roll, pitch and
yaw in the hold before the maneuver (sans-I/O, pure numbers; docs/identify.md, *The
identification flight*).

A stock autopilot's rate loop (``output: rates``) is pinned best by rate *steps*: a step
faster than the loop separates its delay from its lag, which a maneuver's smooth rates trade
for each other. With ``--identify-excitation`` the hold before the first maneuver sends, on
one axis at a time, a mirrored doublet of body-rate set-points: ``+a`` for ``step_s``,
``-a`` for ``2 step_s``, ``+a`` for ``step_s`` (two doublets back to back), then 0 for
``rest_s`` (the autopilot's own loop stops the rotation), then ``settle_s`` in which the hover
LQR alone holds the point again. Roll, pitch, yaw, repeated ``repeats`` times, every second
round with the signs reversed. The rates' integral is zero, so the attitude comes back, and so
is the attitude's, so the velocity the tilt gave comes back too: the hover LQR takes the axis
back at rest, near its point. The peak attitude change is ``a * step_s`` (defaults: 0.5 rad/s
for 0.15 s, 0.075 rad = 4.3 deg, against the hold's 15 deg and 1.5 rad/s bounds), the peak
speed about ``g a step_s^2`` (0.11 m/s). What the hover LQR finds when it takes an axis back
(a few centimetres off its point, the drift of any attitude offset over the pulse) it answers
with a torque that the rate loop's inverse turns into a rate: on the emulator a plain doublet
of 0.6 rad/s for 0.2 s per half came to 71 % of the hold's rate bound, this pulse at 0.6 rad/s
and 0.2 s to 75 %, at the defaults to 40 %. The rates are sent as ordinary SET_ATTITUDE_TARGET commands,
so the ``.tlog`` holds them as it holds every command, and ``mavreg identify`` fits them
with the rest of the flight.

:class:`~mavreg.daemon.flight.hover_phases.Hold` runs it; :class:`~mavreg.daemon.flight.output.RateOutput`
puts the pulse's rate on its axis in place of the hover LQR's. The rotors output has no
rate loop to excite: a supervisor refuses the excitation there (:func:`check_output`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

__all__ = ["ExcitationParams", "RateStep", "AXIS_NAMES", "check_output", "EXCITATION_START", "EXCITATION_END"]

EXCITATION_START = "start:"
EXCITATION_END = "end:"
"""The excitation's two STATUSTEXTs read ``mavreg excitation: start: ...`` and ``mavreg
excitation: end: ...`` (the daemon's announcements, so in the ``.tlog``): ``mavreg identify``
finds the pulses' window by them."""

AXIS_NAMES = ("roll", "pitch", "yaw")

MAX_AMPLITUDE_RAD_S = 1.0
"""The largest pulse amplitude accepted: 2/3 of the hold's 1.5 rad/s rate-error bound."""
MAX_TURN_RAD = 0.2
"""The largest attitude change a pulse may ask (11.5 deg, the hold bounds 15)."""



class RateStep(NamedTuple):
    """The rate set-point the excitation puts on one axis (:meth:`ExcitationParams.rate_at`)."""

    axis: int
    """0 roll, 1 pitch, 2 yaw."""
    rate_rad_s: float

@dataclass(frozen=True)
class ExcitationParams:
    """The rate pulses of the identification flight (SI units; off unless given)."""

    amplitude_rad_s: tuple[float, float, float] = (0.5, 0.5, 0.1)
    """The pulses' rate on roll, pitch and yaw (rad/s, body axes); the middle step changes
    the rate by twice that. Yaw's is smaller: a quadrotor's yaw authority is small, and a
    step it cannot follow at once measures its torque limit, not its loop (the emulator's
    yaw step reaches 90 % at 101 ms up to 0.2 rad/s, at 161 ms at 0.5 rad/s, and a pulse of
    0.2 rad/s read 54 ms and 52 ms for its 39 ms and 40 ms; its roll and pitch are linear
    to 1 rad/s)."""
    step_s: float = 0.15
    """The pulse's first and last steps (the middle one is twice as long): several times a
    stock rate loop's 30-60 ms response."""
    rest_s: float = 0.2
    """After each pulse, the axis is held at 0 rad/s this long (the rotation stopped by the
    autopilot's loop, before the hover LQR takes the axis back)."""
    settle_s: float = 0.6
    """Then the hover LQR alone re-levels and holds the point."""
    repeats: int = 3
    """Rounds of roll, pitch and yaw pulses (the second with the signs reversed)."""

    def __post_init__(self):
        a = tuple(float(v) for v in self.amplitude_rad_s)
        if len(a) != 3 or not all(0.0 < v <= MAX_AMPLITUDE_RAD_S for v in a):
            raise ValueError(f"excitation amplitudes must be 3 values in (0, {MAX_AMPLITUDE_RAD_S:g}] rad/s, "
                             f"got {self.amplitude_rad_s}")
        if not (0.05 <= self.step_s <= 0.5 and 0.0 <= self.rest_s <= 1.0 and 0.0 <= self.settle_s <= 5.0
                and 1 <= self.repeats <= 10):
            raise ValueError(f"excitation step {self.step_s:g} s (0.05-0.5), rest {self.rest_s:g} s (0-1), "
                             f"settle {self.settle_s:g} s (0-5), repeats {self.repeats} (1-10) out of range")
        if max(a) * self.step_s > MAX_TURN_RAD + 1e-12:
            raise ValueError(f"an excitation step turns the vehicle {max(a) * self.step_s:.3f} rad "
                             f"(amplitude x step), more than {MAX_TURN_RAD:g} rad")
        object.__setattr__(self, "amplitude_rad_s", a)

    @property
    def slot_s(self) -> float:
        """One pulse, its rest and its settling."""
        return 4.0 * self.step_s + self.rest_s + self.settle_s

    @property
    def duration_s(self) -> float:
        """The whole excitation: ``repeats`` rounds of three pulses."""
        return 3 * self.repeats * self.slot_s

    def rate_at(self, t_s: float) -> RateStep | None:
        """(axis 0 roll / 1 pitch / 2 yaw, rate rad/s) set ``t_s`` after the excitation began
        (the rest after a pulse: rate 0); None outside (settling, before, after): the hover
        LQR's rates go out."""
        if not (0.0 <= t_s < self.duration_s) or not math.isfinite(t_s):
            return None
        k = int((t_s + 1e-9) // self.slot_s)        # a slot's start, though rounded, is in it
        u = max(0.0, t_s - k * self.slot_s)
        axis, round_ = k % 3, k // 3
        q = int((u + 1e-9) // self.step_s)            # the pulse's quarter: + - - +
        if q >= 4:
            return RateStep(axis, 0.0) if u + 1e-9 < 4.0 * self.step_s + self.rest_s else None
        sign = 1.0 if round_ % 2 == 0 else -1.0
        return RateStep(axis, (-sign if q in (1, 2) else sign) * self.amplitude_rad_s[axis])

    def describe(self) -> str:
        """One line for the event and the STATUSTEXT."""
        a = "/".join(f"{v:g}" for v in self.amplitude_rad_s)
        return (f"rate pulses roll, pitch, yaw +-{a} rad/s, {self.step_s:g}/{2 * self.step_s:g}/{self.step_s:g} s, "
                f"0 for {self.rest_s:g} s, {self.settle_s:g} s to settle, {self.repeats} rounds "
                f"({self.duration_s:.1f} s)")


def check_output(excitation: ExcitationParams | None, output_kind: str) -> None:
    """Refuse (ValueError, one line) an excitation for an output that has no rate loop."""
    if excitation is not None and output_kind != "rates":
        raise ValueError("the identification excitation steps an autopilot's rate set-points: it needs "
                         f"--output rates (this flight's output is {output_kind})")
