r"""The design model: the paper's quadrotor, eqs 6-17.

State ``x = (p1 p2 p3, phi theta psi, v1 v2 v3, p q r)``: NED position, roll-pitch-yaw,
body-frame linear velocity, body-frame angular velocity. Input ``u = (f, g1, g2, g3)``:
total thrust along body -z (N) and body torques (N m).

.. math::
    \dot{\mathbf p} = R\mathbf v,\quad
    \dot{\mathbf v} = -\boldsymbol\omega\times\mathbf v + g R^T e_3 - \tfrac{f}{m} e_3,\quad
    J\dot{\boldsymbol\omega} = -\boldsymbol\omega\times J\boldsymbol\omega + \boldsymbol\gamma,

with the Euler-angle kinematics of eqs 9-11. Works on complex arrays (complex step).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.vehicle import G, VehicleParams
from .rotation import euler_rates_matrix, rpy_to_matrix

__all__ = ["QuadrotorModel", "NX", "NU"]

NX = 12
NU = 4


@dataclass(frozen=True)
class QuadrotorModel:
    """Rigid-body parameters of eqs 6-17 (mass, diagonal inertia, gravity)."""

    mass_kg: float
    inertia_kg_m2: tuple[float, float, float]
    g: float = G

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams) -> "QuadrotorModel":
        return cls(vehicle.mass_kg, tuple(vehicle.inertia_kg_m2))

    def f(self, x, u) -> np.ndarray:
        """State derivative dx/dt = f(x, u) (eqs 6-17); x (12,) or (12, N), u (4,) or (4, N)."""
        phi, theta, psi = x[3], x[4], x[5]
        v = x[6:9]
        p, q, r = x[9], x[10], x[11]
        jx, jy, jz = self.inertia_kg_m2
        R = rpy_to_matrix(phi, theta, psi)
        # einsum so that x may also be a batch (12, N) of states.
        pdot = np.einsum("ij...,j...->i...", R, v)
        eul = np.einsum("ij...,j...->i...", euler_rates_matrix(phi, theta), x[9:12])
        thrust, g1, g2, g3 = u[0], u[1], u[2], u[3]
        m, g = self.mass_kg, self.g
        v1, v2, v3 = v[0], v[1], v[2]
        vdot = np.array([
            r * v2 - q * v3 - g * np.sin(theta),
            -r * v1 + p * v3 + g * np.sin(phi) * np.cos(theta),
            q * v1 - p * v2 + g * np.cos(theta) * np.cos(phi) - thrust / m,
        ])
        wdot = np.array([
            q * r * (jy - jz) / jx + g1 / jx,
            p * r * (jz - jx) / jy + g2 / jy,
            p * q * (jx - jy) / jz + g3 / jz,
        ])
        return np.concatenate([pdot, eul, vdot, wdot])

    def hover_input(self) -> np.ndarray:
        """Input that holds a level hover: f = m g, no torque."""
        return np.array([self.mass_kg * self.g, 0.0, 0.0, 0.0])
