"""How the maneuver regulator allocates rotor forces and governs its speed: two optional
sections of the controller YAML, ``allocation:`` and ``speed_governor:``.

What each setting does and why each default is what it is: docs/governor.md. Units are SI;
the names carry them.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from .ranges import ROTOR_THRUST_N, within

# Lower bounds (1 cm/s^2, 1 cm/s, 1 ms, 1 %) are where each setting stops meaning anything:
# a speed deficit of 1 cm/s is the estimate's noise, a 1 ms filter is one control period.

__all__ = ["AllocationParams", "SpeedGovernorParams", "ALLOCATION_METHODS", "told_rotor_limit"]

ALLOCATION_METHODS = ("torques_first", "per_rotor_clip")
"""``torques_first``: rotor forces within [0, limit], the yaw torque giving way first, then
the collective thrust, then roll and pitch together (:func:`mavreg.model.mixer.torques_first`).
``per_rotor_clip``: eq 34 inverted, yaw then lift where a rotor would pull, nothing done at
the top (the rotors clip each force on their own; the paper's allocation)."""


@dataclass(frozen=True)
class AllocationParams:
    """The regulator's map from the wrench u = (f, gamma) to the four rotor forces."""

    method: str = field(default="torques_first", metadata={"choices": ALLOCATION_METHODS})
    max_rotor_thrust_n: float | None = field(default=None, metadata=ROTOR_THRUST_N)
    """The rotor force the allocation (and the speed governor) may count on; None: the vehicle
    file's ``max_rotor_thrust_n``. A vehicle whose rotors give less than its file says (a
    saturation experiment, a derated motor) is told here, while the plan keeps the file's."""


@dataclass(frozen=True)
class SpeedGovernorParams:
    r"""The speed the regulator regulates to: the profile re-timed from where the vehicle is.

    The along-track speed error the LQR sees is kept within ``speed_band_m_s``: a vehicle
    slowed down (a gust) is given a governed speed :math:`v_g(s)` that starts at its own
    speed and returns to the profile at ``recovery_accel_m_s2``, and never exceeds the
    profile. The nominal is re-timed to :math:`v_g` (velocities, rates, the thrust vector
    for the centripetal and along-track accelerations at that speed), so the feedforward
    stays consistent. Knowing the rotor limit, the governor also caps the speed where the
    re-timed nominal would ask for more than ``thrust_share`` of four rotors' thrust.
    """

    enabled: bool = False
    """False: the paper's regulator, which regulates to the profile's speed at s."""
    recovery_accel_m_s2: float = field(default=3.0, metadata=within(0.01, 20.0))
    """Along-track acceleration at which the governed speed returns to the profile (and at
    which it slows down ahead of a thrust-limited stretch)."""
    recovery_time_constant_s: float = field(default=0.3, metadata={"min": 0.0, "max": 5.0})
    """The last of the deficit closes exponentially with this time constant, so that the
    acceleration asked for fades out where the governed speed meets the profile."""
    speed_band_m_s: float = field(default=0.1, metadata=within(0.01, 5.0))
    """Largest along-track speed deficit the LQR is left to fight; beyond it the governed
    speed drops to the vehicle's speed plus this band."""
    speed_gain_per_s: float = field(default=5.0, metadata={"min": 0.0, "max": 50.0})
    """What the governed speed asks beyond the band (a vehicle pushed backwards) is fed
    forward as an along-track acceleration of this gain times the excess, through the thrust
    vector, instead of being left to the LQR."""
    max_accel_m_s2: float = field(default=12.0, metadata=within(0.01, 20.0))
    """Bound on that acceleration (12 m/s^2: 51 deg of tilt, 1.6 times the hover thrust)."""
    accel_time_constant_s: float = field(default=0.05, metadata=within(1e-3, 1.0))
    """The along-track acceleration fed forward follows the governed one through a critically
    damped second-order filter of this time constant: a recovery that starts turns the
    nominal's thrust at once (3 m/s^2 is 17 deg), which a step, or a step of its rate, would
    turn into an attitude error (with a 20 ms rotor lag the paper's gains ring)."""
    max_jerk_m_s3: float = field(default=60.0, metadata=within(0.01, 1000.0))
    """Bound on that acceleration's rate of change."""
    thrust_share: float = field(default=0.9, metadata=within(0.01, 1.0))
    """Share of four rotors' thrust the re-timed nominal may ask for; the rest is left for
    the torques and the feedback."""
    cap_speed_for_thrust: bool = True
    """Cap the speed where the re-timed nominal would need more thrust than ``thrust_share``
    of four rotors give (a nominal that needs none is left alone)."""


def told_rotor_limit(allocation: AllocationParams, rotor_limit_n: float | None) -> AllocationParams:
    """``allocation`` told that the rotors give ``rotor_limit_n`` at most (a saturation run whose
    limit the controller knows); unchanged when it is None."""
    if rotor_limit_n is None:
        return allocation
    return dataclasses.replace(allocation, max_rotor_thrust_n=float(rotor_limit_n))
