r"""Rotor mixing, paper eq 34, plus configuration (rotor order of docs/conventions.md).

.. math::
    \begin{bmatrix}f\\\gamma_1\\\gamma_2\\\gamma_3\end{bmatrix} =
    \begin{bmatrix}1&1&1&1\\0&-l&0&l\\l&0&-l&0\\-k&k&-k&k\end{bmatrix}
    \begin{bmatrix}f_1\\f_2\\f_3\\f_4\end{bmatrix}
"""
from __future__ import annotations

import numpy as np

__all__ = ["mixer_matrix", "Mixer", "lift_to_zero", "yaw_then_lift", "torques_first", "collective_first"]


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

    @classmethod
    def from_vehicle(cls, vehicle) -> "Mixer":
        """The mixer of a vehicle file's airframe (``arm_length_m``, ``drag_torque_ratio_m``)."""
        return cls(vehicle.arm_length_m, vehicle.drag_torque_ratio_m)

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


def yaw_then_lift(mixer_inverse, u, max_rotor_thrust_n: float) -> np.ndarray:
    """Rotor forces for ``u = (f, g1, g2, g3)`` when a rotor would have to pull: the yaw torque
    gives way first, as far as it helps, then :func:`lift_to_zero` lifts all four.

    The yaw torque is the expensive one (a yaw torque of 1 N m needs ``1/(4k)`` = 15.6 N of
    rotor difference on the MK-Quadro, roll or pitch 1.7 N) and the least needed to stay on a
    path; PX4's mixer also drops yaw first. The yaw torque is scaled by the largest
    ``beta`` in [0, 1] that keeps every rotor that the roll, pitch and thrust alone leave
    non-negative from going below zero.
    """
    Minv = np.asarray(mixer_inverse, dtype=float)
    u = np.asarray(u, dtype=float)
    base = Minv[:, :3] @ u[:3]
    yaw = Minv[:, 3] * u[3]
    f = base + yaw
    if f.min() >= 0.0:
        return f
    beta = 1.0
    for b, y in zip(base, yaw):
        if b + y < 0.0 and y != 0.0:     # no yaw share: the yaw torque cannot help this rotor
            beta = min(beta, max(b, 0.0) / -y)
    return lift_to_zero(base + beta * yaw, max_rotor_thrust_n)


def torques_first(mixer_inverse, u, max_rotor_thrust_n: float) -> np.ndarray:
    r"""Rotor forces within :math:`[0, F]` for ``u = (f, g1, g2, g3)``: the torques are kept
    and the collective thrust is given up first.

    With :math:`b = M^{-1}_{:,0:3} u_{0:3}` (thrust, roll, pitch) and
    :math:`y = M^{-1}_{:,3} u_3` (yaw), in this order:

    1. :math:`f = b + y` when every force is within :math:`[0, F]` (eq 34 inverted, exact);
    2. the yaw torque gives way: :math:`y \to \beta y` with the largest :math:`\beta \in [0, 1]`
       that keeps every rotor that :math:`b` leaves within :math:`[0, F]` there (at the low
       end exactly :func:`yaw_then_lift`'s :math:`\beta`);
    3. the collective moves: all four forces shift by the same amount, the least that brings
       them within :math:`[0, F]` (down at the top: the thrust is given up; up at the
       bottom: :func:`lift_to_zero`), roll, pitch and the remaining yaw torque exact. This
       is possible while the forces' spread :math:`\max f - \min f \le F`;
    4. otherwise roll and pitch themselves do not fit (the yaw is gone by then): the torques
       are scaled by :math:`F/(\max f - \min f)` and the collective is the one left, the
       forces spanning exactly :math:`[0, F]`.

    Wherever :func:`yaw_then_lift` gives forces within :math:`[0, F]`, this gives the same. The
    yaw gives way first at both ends for the reason :func:`yaw_then_lift` gives: it is the
    expensive torque and the least needed to stay on a path.
    Per-rotor clipping at :math:`F` instead keeps the collective and loses the torque of the
    clipped rotor: at the bottom of the barrel roll's loop, where the nominal asks every
    rotor for about 10 N, rotors saturated at 7 N can give no roll torque at all.

    Parameters
    ----------
    mixer_inverse : (4, 4) array_like
        The inverse of eq 34's matrix.
    u : (4,) array_like
        Thrust (N) and body torques (N m) asked for.
    max_rotor_thrust_n : float
        The rotors' limit F.
    """
    Minv = np.asarray(mixer_inverse, dtype=float)
    u = np.asarray(u, dtype=float)
    F = float(max_rotor_thrust_n)
    base = Minv[:, :3] @ u[:3]
    yaw = Minv[:, 3] * u[3]
    f = base + yaw
    if f.min() >= 0.0 and f.max() <= F:
        return f
    beta = 1.0
    for b, y in zip(base, yaw):         # a rotor out of range with the yaw's help: no yaw
        if b + y < 0.0 and y != 0.0:
            beta = min(beta, max(b, 0.0) / -y) if y < 0.0 else 0.0
        elif b + y > F and y != 0.0:
            beta = min(beta, max(F - b, 0.0) / y) if y > 0.0 else 0.0
    f = base + beta * yaw
    low, high = float(f.min()), float(f.max())
    if high - low <= F:
        return f - low if low < 0.0 else (f - (high - F) if high > F else f)
    return (f - low) * (F / (high - low))


def collective_first(thrust_n: float, torque_n_m, mixer_inverse, max_rotor_thrust_n: float) -> np.ndarray:
    """Rotor forces in [0, max] for a wrench, giving up collective thrust first (the
    recovery's policy, :mod:`mavreg.control.controllers.recovery`: the attitude is what must be kept).

    Returns rotor forces f with ``M f = (thrust', torque')``: the torque exactly when some
    collective makes it feasible (thrust' is then the feasible value nearest ``thrust_n``);
    otherwise the yaw torque is reduced first, then roll and pitch are scaled together.
    """
    a = mixer_inverse[:, 0]
    B = mixer_inverse[:, 1:]
    fmax = float(max_rotor_thrust_n)

    def interval(t):
        b = B @ t
        return float(np.max(-b / a)), float(np.min((fmax - b) / a)), b

    def feasible(t):
        lo, hi, _ = interval(t)
        return lo <= hi

    tau = np.asarray(torque_n_m, dtype=float)
    if not feasible(tau):
        roll_pitch = tau * np.array([1.0, 1.0, 0.0])
        if feasible(roll_pitch):
            yaw = tau - roll_pitch
            tau = roll_pitch + _largest_scale(feasible, roll_pitch, yaw) * yaw
        else:
            tau = _largest_scale(feasible, np.zeros(3), roll_pitch) * roll_pitch
    lo, hi, b = interval(tau)
    return np.clip(a * min(max(thrust_n, lo), hi) + b, 0.0, fmax)


def _largest_scale(feasible, base: np.ndarray, direction: np.ndarray) -> float:
    """Largest k in [0, 1] with ``feasible(base + k direction)`` (``base`` is feasible)."""
    k_lo, k_hi = 0.0, 1.0
    for _ in range(30):
        k = 0.5 * (k_lo + k_hi)
        if feasible(base + k * direction):
            k_lo = k
        else:
            k_hi = k
    return k_lo
