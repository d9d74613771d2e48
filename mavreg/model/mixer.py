r"""Rotor mixing, paper eq 34, plus configuration (rotor order of conventions.md).

.. math::
    \begin{bmatrix}f\\\gamma_1\\\gamma_2\\\gamma_3\end{bmatrix} =
    \begin{bmatrix}1&1&1&1\\0&-l&0&l\\l&0&-l&0\\-k&k&-k&k\end{bmatrix}
    \begin{bmatrix}f_1\\f_2\\f_3\\f_4\end{bmatrix}
"""
from __future__ import annotations

import numpy as np

__all__ = ["mixer_matrix", "Mixer", "lift_to_zero"]


def mixer_matrix(arm_length_m: float, drag_torque_ratio_m: float) -> np.ndarray:
    """The 4x4 matrix M of eq 34: u = M f_rotors."""
    l, k = arm_length_m, drag_torque_ratio_m
    return np.array([
        [1.0, 1.0, 1.0, 1.0],
        [0.0, -l, 0.0, l],
        [l, 0.0, -l, 0.0],
        [-k, k, -k, k],
    ])


class Mixer:
    """Eq 34 and its inverse, with the inverse formed once."""

    def __init__(self, arm_length_m: float, drag_torque_ratio_m: float):
        self.matrix = mixer_matrix(arm_length_m, drag_torque_ratio_m)
        self.inverse = np.linalg.inv(self.matrix)

    def to_wrench(self, rotor_forces_n) -> np.ndarray:
        """(f, g1, g2, g3) produced by rotor forces (f1..f4)."""
        return self.matrix @ np.asarray(rotor_forces_n)

    def to_rotors(self, u) -> np.ndarray:
        """Rotor forces (f1..f4) that produce u = (f, g1, g2, g3) exactly (no saturation)."""
        return self.inverse @ np.asarray(u)


def lift_to_zero(rotor_forces_n, max_rotor_thrust_n: float) -> np.ndarray:
    """Rotors cannot pull: a force below zero is met by lifting all four, torques kept.

    Where eq 34 inverted asks a rotor for f_min < 0, all four rotors get -f_min more, as far
    as the top limit leaves room: the torques (differences) are unchanged and only the
    collective thrust grows, briefly (PX4's "airmode" at the low end). Plain per-rotor
    clipping at 0 would instead drop that rotor's share of the torque. Nothing changes when
    every force is already non-negative; forces above the limit are left to the caller.
    """
    f = np.asarray(rotor_forces_n, dtype=float)
    low = float(f.min())
    if low >= 0.0:
        return f
    room = max(max_rotor_thrust_n - float(f.max()), 0.0)
    return f + min(-low, room)
