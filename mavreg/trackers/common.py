"""What a time-indexed tracker returns, and how it turns its wrench into rotor forces.

The trackers allocate exactly as the maneuver regulator does
(:func:`mavreg.model.mixer.yaw_then_lift` on the inverse of eq 34): where a rotor would have
to pull, the yaw torque gives way first, then all four rotors are lifted; nothing is clipped
at the top (the plant clips). So a comparison of the three controllers differs only in the
feedback law.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.vehicle import VehicleParams
from ..model.mixer import Mixer, yaw_then_lift

__all__ = ["TrackerOutput", "Allocator", "cross3"]


@dataclass(frozen=True)
class TrackerOutput:
    """One step of a tracker."""

    t: float
    """Maneuver time the reference was taken at (s)."""
    s_reference: float
    """Arc length of the timed reference at t (m; beyond the path's length after its end)."""
    u: np.ndarray
    """(f, g1, g2, g3) asked for (N, N m)."""
    rotor_forces_n: np.ndarray
    """(4,) rotor forces after the allocation."""


class Allocator:
    """The regulator's allocation for a vehicle: ``rotors(u)`` for a wrench u (4,)."""

    def __init__(self, vehicle: VehicleParams):
        self.mixer_inverse = Mixer.from_vehicle(vehicle).inverse
        self.max_rotor_thrust_n = float(vehicle.max_rotor_thrust_n)

    def rotors(self, u) -> np.ndarray:
        """Rotor forces for ``u`` = (f, g1, g2, g3): eq 34 inverted, yaw first to give way
        where a rotor would pull, then all four lifted."""
        return yaw_then_lift(self.mixer_inverse, np.asarray(u, dtype=float), self.max_rotor_thrust_n)


def cross3(a, b) -> np.ndarray:
    """a x b of two 3-vectors (numpy's ``cross`` costs ten times as much on small vectors)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])
