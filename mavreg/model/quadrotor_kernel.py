r"""The design model's derivative as a compiled kernel (:func:`mavreg.accel.njit`).

:func:`plant_rhs` is :meth:`mavreg.model.quadrotor.QuadrotorModel.f` (eqs 6-17, with the
optional drag of :mod:`mavreg.model.drag_kernel`) written out on scalars, the same operations
in the same order, for one run's inertia: given x (12,) and floats it fills ``out`` (12,).
:func:`rk4_step` is one classical RK4 step of it, with an external force held over the step:
what the batch simulator (:mod:`mavreg.sim.batch_kernel`) and the sequential one
(:func:`mavreg.sim.closed_loop.simulate`, roll-pitch-yaw attitude) step the plant with.
``tests/unit/test_quadrotor_kernel.py`` holds both to the numpy reference.
"""
from __future__ import annotations

import numpy as np

from ..accel import njit
from .drag_kernel import body_drag, rotor_plane_scale

__all__ = ["plant_rhs", "plant_rhs_compiled", "rk4_step", "angular_acceleration"]


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


@njit
def _force_rhs(x, u0, u1, u2, u3, force, plant, jx, jy, jz, out):
    """:func:`plant_rhs` plus, when ``force[3]`` is not 0, the external acceleration
    ``force[:3]`` (NED, m/s^2) in the body frame, :math:`R^T a`."""
    plant_rhs(x, u0, u1, u2, u3, plant, jx, jy, jz, out)
    if force[3] != 0.0:
        cf, sf = np.cos(x[3]), np.sin(x[3])
        ct, st = np.cos(x[4]), np.sin(x[4])
        cp, sp = np.cos(x[5]), np.sin(x[5])
        a0, a1, a2 = force[0], force[1], force[2]
        out[6] += cp * ct * a0 + sp * ct * a1 + -st * a2
        out[7] += (-sp * cf + cp * st * sf) * a0 + (cp * cf + sp * st * sf) * a1 + ct * sf * a2
        out[8] += (sp * sf + cp * st * cf) * a0 + (-cp * sf + sp * st * cf) * a1 + ct * cf * a2


@njit
def rk4_step(x, u0, u1, u2, u3, force, plant, jx, jy, jz, dt, work):
    """One classical RK4 step of :func:`plant_rhs` from x, in place: the input held, and the
    external acceleration ``force`` = (a_N, a_E, a_D, on) held too (``on`` 0: none);
    ``work`` (5, 12) is scratch."""
    k1, k2, k3, k4, y = work[0], work[1], work[2], work[3], work[4]
    half, sixth = 0.5 * dt, dt / 6.0
    _force_rhs(x, u0, u1, u2, u3, force, plant, jx, jy, jz, k1)
    for j in range(12):
        y[j] = x[j] + half * k1[j]
    _force_rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k2)
    for j in range(12):
        y[j] = x[j] + half * k2[j]
    _force_rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k3)
    for j in range(12):
        y[j] = x[j] + dt * k3[j]
    _force_rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k4)
    for j in range(12):
        x[j] = x[j] + sixth * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])


plant_rhs_compiled = plant_rhs
"""The former name (the kernel is compiled where numba is)."""


@njit
def angular_acceleration(jx, jy, jz, wx, wy, wz, g1, g2, g3):
    r""":math:`J^{-1}(\gamma - \omega \times J\omega)` of the body rates (eqs 12-14), in the
    form the state predictor's integration uses (:mod:`mavreg.control.estimation.predictor_kernel`)."""
    return (g1 + (jy - jz) * wy * wz) / jx, (g2 + (jz - jx) * wx * wz) / jy, (g3 + (jx - jy) * wx * wy) / jz
