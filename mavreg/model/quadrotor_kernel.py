r"""The design model's derivative as a compiled kernel (:func:`mavreg.accel.njit`).

:func:`plant_rhs` is :meth:`mavreg.model.quadrotor.QuadrotorModel.f` (eqs 6-17, with the
optional drag of :mod:`mavreg.model.drag_kernel`) written out on scalars, the same operations
in the same order, for one run's inertia: given x (12,) and floats it fills ``out`` (12,).
The batch simulator (:mod:`mavreg.sim.batch_kernel`) steps it by RK4;
``tests/unit/test_quadrotor_kernel.py`` holds it to the numpy reference.
"""
from __future__ import annotations

import numpy as np

from ..accel import njit
from .drag_kernel import body_drag, rotor_plane_scale

__all__ = ["plant_rhs", "plant_rhs_compiled", "angular_acceleration"]


@njit
def plant_rhs(x, u0, u1, u2, u3, plant, jx, jy, jz, out):
    r"""dx/dt into ``out`` for state x and input :math:`u = (f, \gamma_1, \gamma_2, \gamma_3)`;
    ``plant`` = (mass, g, c_xy, c_z, c_parasitic, e), e the rotor-plane drag's thrust exponent
    (:func:`mavreg.model.drag_kernel.rotor_plane_scale`); jx, jy, jz: the run's inertia."""
    m, g, cxy, cz, cpar, e = plant
    phi, theta, psi = x[3], x[4], x[5]
    v1, v2, v3 = x[6], x[7], x[8]
    p, q, r = x[9], x[10], x[11]
    cf, sf = np.cos(phi), np.sin(phi)
    ct, st = np.cos(theta), np.sin(theta)
    cp, sp = np.cos(psi), np.sin(psi)
    tt = np.tan(theta)
    out[0] = cp * ct * v1 + (-sp * cf + cp * st * sf) * v2 + (sp * sf + cp * st * cf) * v3
    out[1] = sp * ct * v1 + (cp * cf + sp * st * sf) * v2 + (-cp * sf + sp * st * cf) * v3
    out[2] = -st * v1 + ct * sf * v2 + ct * cf * v3
    out[3] = p + sf * tt * q + cf * tt * r
    out[4] = cf * q + -sf * r
    out[5] = sf / ct * q + cf / ct * r
    out[6] = r * v2 - q * v3 - g * st
    out[7] = -r * v1 + p * v3 + g * sf * ct
    out[8] = q * v1 - p * v2 + g * ct * cf - u0 / m
    if cxy != 0.0 or cz != 0.0 or cpar != 0.0:
        d1, d2, d3 = body_drag(v1, v2, v3, cxy * rotor_plane_scale(u0, m * g, e), cz, cpar)
        out[6] = out[6] + d1 / m
        out[7] = out[7] + d2 / m
        out[8] = out[8] + d3 / m
    out[9] = q * r * (jy - jz) / jx + u1 / jx
    out[10] = p * r * (jz - jx) / jy + u2 / jy
    out[11] = p * q * (jx - jy) / jz + u3 / jz


plant_rhs_compiled = plant_rhs
"""The former name (the kernel is compiled where numba is)."""


@njit
def angular_acceleration(jx, jy, jz, wx, wy, wz, g1, g2, g3):
    r""":math:`J^{-1}(\gamma - \omega \times J\omega)` of the body rates (eqs 12-14), in the
    form the state predictor's integration uses (:mod:`mavreg.control.estimation.predictor_kernel`)."""
    return (g1 + (jy - jz) * wy * wz) / jx, (g2 + (jz - jx) * wx * wz) / jy, (g3 + (jx - jy) * wx * wy) / jz
