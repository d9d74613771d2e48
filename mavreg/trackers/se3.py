r"""The geometric tracking controller on SE(3) of Lee, Leok and McClamroch.

"Geometric tracking control of a quadrotor UAV on SE(3)" (CDC 2010), Section III, with the
reference from the timed nominal (:class:`~.timed.TimedNominal`): position :math:`x_d`,
velocity :math:`v_d`, acceleration :math:`\ddot x_d`, the heading direction
:math:`b_{1d} = \bar R e_1` (the nominal body x axis), and as attitude feedforward the
nominal's body rates :math:`\Omega_d = \bar\omega(t)` and their derivative
:math:`\dot\Omega_d` (no jerk or snap of the feedback). NED with body z down, as the paper:
:math:`m\ddot x = m g e_3 - f R e_3`.

.. math::
    e_x = x - x_d,\quad e_v = v - v_d,\quad
    F_d = -k_x e_x - k_v e_v - m g e_3 + m \ddot x_d,\\
    b_{3d} = -F_d / \|F_d\|,\quad b_{2d} = \frac{b_{3d}\times b_{1d}}{\|b_{3d}\times b_{1d}\|},\quad
    R_d = [\,b_{2d}\times b_{3d},\ b_{2d},\ b_{3d}\,],\quad f = -F_d^T R e_3,\\
    e_R = \tfrac12 (R_d^T R - R^T R_d)^\vee,\quad e_\Omega = \Omega - R^T R_d \Omega_d,\\
    M = -k_R e_R - k_\Omega e_\Omega + \Omega\times J\Omega
        - J(\hat\Omega R^T R_d \Omega_d - R^T R_d \dot\Omega_d).

On the nominal, :math:`F_d = -\bar f \bar R e_3`, so :math:`R_d = \bar R` and the law returns
the nominal input: the controller flies the nominal exactly from its exact initial state.

**Gains** (:class:`Se3Gains`), as natural frequencies and damping ratios on this vehicle's
mass and roll inertia (the gains are scalars, as in the paper). Position: the paper's
simulation gains, :math:`k_x = 16 m`, :math:`k_v = 5.6 m`: 4 rad/s with damping 0.7, the
stiffness of the maneuver regulator's LQR, whose lateral poles on the hover linearization
are at -2.9 ± 3.3j (4.4 rad/s). Attitude: 30 rad/s with damping 0.8. The paper's attitude
gains (:math:`k_R = 8.81`, :math:`k_\Omega = 2.54` on :math:`J_{xx} = 0.0820` kg m², an
overdamped loop at 10.4 rad/s, damping 1.5, whose slow pole is at 4.1 rad/s) do not work
with the nominal's body rates as :math:`\Omega_d`: the paper's :math:`\Omega_d` is the
derivative of :math:`R_d`, which carries the position feedback's rate, and without it the
attitude loop is the position loop's only lag. On the hover linearization the cascade
``(k_x + k_v s) / (m s^2)`` times the attitude loop then crosses over at 4.4 rad/s with no
phase margin (a sustained ±14° roll oscillation at 0.8 Hz, measured on the run-out); at
30 rad/s and 0.8 the margin is 46° at 6.1 rad/s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..config.vehicle import G
from ..model.rotation import rpy_to_matrix
from .common import Allocator, TrackerOutput, cross3
from .timed import TimedNominal

__all__ = ["Se3Gains", "Se3Tracker", "LEE_ATTITUDE_RAD_S", "LEE_ATTITUDE_DAMPING"]

_E3 = np.array([0.0, 0.0, 1.0])
LEE_ATTITUDE_RAD_S = math.sqrt(8.81 / 0.0820)
"""The paper's attitude gain on its roll inertia, as a natural frequency (10.4 rad/s; not used:
see the module docstring)."""
LEE_ATTITUDE_DAMPING = 2.54 / (2.0 * math.sqrt(8.81 * 0.0820))
"""The paper's attitude damping ratio (1.5)."""


@dataclass(frozen=True)
class Se3Gains:
    """Natural frequencies (rad/s) and damping ratios of the position and attitude loops."""

    position_rad_s: float = 4.0
    position_damping: float = 0.7
    attitude_rad_s: float = 30.0
    attitude_damping: float = 0.8

    def __post_init__(self):
        if min(self.position_rad_s, self.position_damping, self.attitude_rad_s, self.attitude_damping) <= 0:
            raise ValueError("SE(3) gains must be positive")


def _vee(S: np.ndarray) -> np.ndarray:
    return np.array([S[2, 1], S[0, 2], S[1, 0]])


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


class Se3Tracker:
    """Lee, Leok and McClamroch's SE(3) tracker on the timed nominal (module docstring).

    Parameters
    ----------
    timed : TimedNominal
    gains : Se3Gains
    lead_s : float
        The nominal input's change over this much time ahead is added to the command (half
        the control period of a zero-order hold, as the regulator leads its feedforward): on
        the nominal the command is then :math:`\bar u(t + t_{lead})`, the regulator's.
    """

    def __init__(self, timed: TimedNominal, gains: Se3Gains = Se3Gains(), lead_s: float = 0.0):
        self.timed = timed
        self.gains = gains
        self.lead_s = float(lead_s)
        v = timed.plan.vehicle
        self.mass_kg = float(v.mass_kg)
        self.J = np.diag(np.asarray(v.inertia_kg_m2, dtype=float))
        jx = float(v.inertia_kg_m2[0])
        self.k_x = self.mass_kg * gains.position_rad_s ** 2
        self.k_v = 2.0 * gains.position_damping * gains.position_rad_s * self.mass_kg
        self.k_R = jx * gains.attitude_rad_s ** 2
        self.k_W = 2.0 * gains.attitude_damping * gains.attitude_rad_s * jx
        self.allocator = Allocator(v)

    def desired_rotation(self, F_d: np.ndarray, b1d: np.ndarray, b2_nominal: np.ndarray) -> np.ndarray:
        """R_d from the desired force and the heading direction; where b1d is nearly along
        b3d the nominal body y axis, made normal to b3d, stands in for b3d x b1d."""
        b3 = -F_d / np.linalg.norm(F_d)
        c = cross3(b3, b1d)
        n = float(np.linalg.norm(c))
        if n < 0.1:
            c = b2_nominal - (b2_nominal @ b3) * b3
            n = float(np.linalg.norm(c))
        b2 = c / n
        return np.column_stack([cross3(b2, b3), b2, b3])

    def step(self, t: float, x) -> TrackerOutput:
        """The command at maneuver time ``t`` for state ``x`` (12,)."""
        x = np.asarray(x, dtype=float)
        ref = self.timed.reference(float(t))
        R = rpy_to_matrix(*x[3:6])
        W = x[9:12]
        Rbar = rpy_to_matrix(*ref.x[3:6])
        e_x = x[:3] - ref.x[:3]
        e_v = R @ x[6:9] - Rbar @ ref.x[6:9]
        F_d = (-self.k_x * e_x - self.k_v * e_v - self.mass_kg * G * _E3
               + self.mass_kg * ref.acceleration_ned_m_s2)
        f = -float(F_d @ (R @ _E3))
        Rd = self.desired_rotation(F_d, Rbar[:, 0], Rbar[:, 1])
        W_d, dW_d = ref.x[9:12], ref.angular_acceleration_rad_s2
        RtRd = R.T @ Rd
        e_R = 0.5 * _vee(Rd.T @ R - R.T @ Rd)
        e_W = W - RtRd @ W_d
        M = (-self.k_R * e_R - self.k_W * e_W + cross3(W, self.J @ W)
             - self.J @ (_hat(W) @ RtRd @ W_d - RtRd @ dW_d))
        u = np.array([f, *M])
        if self.lead_s:
            u += self.timed.input_at_s(self.timed.s_at(float(t) + self.lead_s)) - ref.u
        return TrackerOutput(float(t), ref.s, u, self.allocator.rotors(u))
