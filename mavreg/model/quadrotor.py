r"""The design model: the paper's quadrotor, eqs 6-17.

State ``x = (p1 p2 p3, phi theta psi, v1 v2 v3, p q r)``: NED position, roll-pitch-yaw,
body-frame linear velocity, body-frame angular velocity. Input ``u = (f, g1, g2, g3)``:
total thrust along body -z (N) and body torques (N m).

.. math::
    \dot{\mathbf p} = R\mathbf v,\quad
    \dot{\mathbf v} = -\boldsymbol\omega\times\mathbf v + g R^T e_3 - \tfrac{f}{m} e_3,\quad
    J\dot{\boldsymbol\omega} = -\boldsymbol\omega\times J\boldsymbol\omega + \boldsymbol\gamma,

with the Euler-angle kinematics of eqs 9-11. Works on complex arrays (complex step).

Optionally (vehicle file: ``rotor_drag_n_s_per_m``, ``parasitic_drag_n_s2_per_m2``) the body
feels aerodynamic drag, which the paper's model leaves out:

.. math::
    m\dot{\mathbf v} \mathrel{+}= -C\mathbf v - c_p|\mathbf v|\mathbf v,\qquad
    C = \mathrm{diag}(c_{xy}, c_{xy}, c_z),

linear rotor drag in the body frame (the same in the rotor plane, as for a symmetric
quadrotor) and quadratic parasitic drag, both on the velocity relative to the ground (the
design knows no wind). Zero coefficients give the paper's model exactly. With
``rotor_drag_thrust_exponent`` e > 0 the rotor-plane coefficient is :math:`c_{xy}(f/(mg))^e`
at the collective thrust f (:func:`mavreg.model.drag.rotor_plane_scale`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config.vehicle import G, VehicleParams
from .drag import body_drag_n, rotor_plane_scale
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
    rotor_drag_n_s_per_m: tuple[float, float] = (0.0, 0.0)
    """Linear body-frame drag (c_xy in the rotor plane, c_z along the thrust axis)."""
    parasitic_drag_n_s2_per_m2: float = 0.0
    rotor_drag_thrust_exponent: float = 0.0
    """e of c_xy (f / (m g))^e (0: a constant c_xy)."""

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams) -> "QuadrotorModel":
        return cls(vehicle.mass_kg, tuple(vehicle.inertia_kg_m2), G,
                   tuple(vehicle.rotor_drag_n_s_per_m), vehicle.parasitic_drag_n_s2_per_m2,
                   vehicle.rotor_drag_thrust_exponent)

    @property
    def hover_thrust_n(self) -> float:
        """m g: the thrust at which the rotor-plane drag is c_xy."""
        return self.mass_kg * self.g

    @property
    def kernel_params(self) -> tuple[float, float, float, float, float, float]:
        """``(mass, g, c_xy, c_z, c_parasitic, e)``: the ``plant`` argument of the compiled
        kernels (:mod:`mavreg.model.quadrotor_kernel`)."""
        cxy, cz = (float(c) for c in self.rotor_drag_n_s_per_m)
        return (float(self.mass_kg), float(self.g), cxy, cz, float(self.parasitic_drag_n_s2_per_m2),
                float(self.rotor_drag_thrust_exponent))

    @property
    def has_drag(self) -> bool:
        return any(self.rotor_drag_n_s_per_m) or self.parasitic_drag_n_s2_per_m2 > 0

    def f(self, x, u) -> np.ndarray:
        """State derivative dx/dt = f(x, u) (eqs 6-17); x (12,) or (12, N), u (4,) or (4, N)."""
        phi, theta, psi = x[3], x[4], x[5]
        v = x[6:9]
        R = rpy_to_matrix(phi, theta, psi)
        # einsum so that x may also be a batch (12, N) of states.
        pdot = np.einsum("ij...,j...->i...", R, v)
        eul = np.einsum("ij...,j...->i...", euler_rates_matrix(phi, theta), x[9:12])
        vdot, wdot = self.body_derivatives(R[2], v, x[9:12], u)
        return np.concatenate([pdot, eul, vdot, wdot])

    def body_derivatives(self, down_row, v, w, u) -> tuple[np.ndarray, np.ndarray]:
        """dv/dt and dw/dt of the body velocity and rates (eqs 7, 12-14 with drag).

        ``down_row`` is the third row of R, :math:`R^T e_3` (gravity's direction in the body
        frame): (3,) or (3, N); v, w (3,) or (3, N); u (4,) or (4, N). The attitude enters
        only through it, so these dynamics hold for any parametrization of the attitude.
        """
        p, q, r = w[0], w[1], w[2]
        jx, jy, jz = self.inertia_kg_m2
        thrust, g1, g2, g3 = u[0], u[1], u[2], u[3]
        m, g = self.mass_kg, self.g
        v1, v2, v3 = v[0], v[1], v[2]
        vdot = np.array([
            r * v2 - q * v3 + g * down_row[0],
            -r * v1 + p * v3 + g * down_row[1],
            q * v1 - p * v2 + g * down_row[2] - thrust / m,
        ])
        if self.has_drag:
            cxy, cz = self.rotor_drag_n_s_per_m
            cxy = cxy * rotor_plane_scale(thrust, m * g, self.rotor_drag_thrust_exponent)
            vdot = vdot + body_drag_n(v, cxy, cz, self.parasitic_drag_n_s2_per_m2) / m
        wdot = np.array([
            q * r * (jy - jz) / jx + g1 / jx,
            p * r * (jz - jx) / jy + g2 / jy,
            p * q * (jx - jy) / jz + g3 / jz,
        ])
        return vdot, wdot

    def hover_input(self) -> np.ndarray:
        """Input that holds a level hover: f = m g, no torque."""
        return np.array([self.mass_kg * self.g, 0.0, 0.0, 0.0])
