r"""The design model's derivative as a compiled kernel (:func:`mavreg.accel.njit`).

:func:`plant_rhs` is :meth:`mavreg.model.quadrotor.QuadrotorModel.f` (eqs 6-17, with the
optional drag of :mod:`mavreg.model.drag_kernel`) written out on scalars, the same operations
in the same order, for one run's inertia: given x (12,) and floats it fills ``out`` (12,).
:func:`rk4_step` is one classical RK4 step of it, with an external force held over the step:
what the batch simulator (:mod:`mavreg.sim.batch_kernel`) and the sequential one
(:func:`mavreg.sim.closed_loop.simulate`, roll-pitch-yaw attitude) step the plant with;
:func:`rk4_so3_step` the step with the attitude as a rotation matrix (the simulator's
``attitude="so3"``). Both share :func:`body_rhs`, the body dynamics.
``tests/unit/test_quadrotor_kernel.py`` holds both to the numpy reference.
"""
from __future__ import annotations

import numpy as np

from ..accel import njit
from .drag_kernel import body_drag, rotor_plane_scale
from .rotation_kernel import mm, mtm, mtv, mv, rpy_matrix

__all__ = ["plant_rhs", "plant_rhs_compiled", "body_rhs", "rk4_step", "rk4_so3_step", "angular_acceleration"]


@njit
def plant_rhs(x, u0, u1, u2, u3, plant, jx, jy, jz, out):
    r"""dx/dt into ``out`` for state x and input :math:`u = (f, \gamma_1, \gamma_2, \gamma_3)`;
    ``plant`` = (mass, g, c_xy, c_z, c_parasitic, e), e the rotor-plane drag's thrust exponent
    (:func:`mavreg.model.drag_kernel.rotor_plane_scale`); jx, jy, jz: the run's inertia."""
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
    body_rhs(-st, ct * sf, ct * cf, v1, v2, v3, p, q, r, u0, u1, u2, u3, plant, jx, jy, jz, out, 6)


@njit
def body_rhs(d0, d1, d2, v1, v2, v3, p, q, r, u0, u1, u2, u3, plant, jx, jy, jz, out, at):
    r"""dv/dt and d\omega/dt into ``out[at:at + 6]``:
    :meth:`~mavreg.model.quadrotor.QuadrotorModel.body_derivatives` (eqs 7, 12-14 with drag)
    with (d0, d1, d2) the third row of R (gravity's direction in the body frame), so for any
    form of the attitude."""
    m, g, cxy, cz, cpar, e = plant
    out[at] = r * v2 - q * v3 + g * d0
    out[at + 1] = -r * v1 + p * v3 + g * d1
    out[at + 2] = q * v1 - p * v2 + g * d2 - u0 / m
    if cxy != 0.0 or cz != 0.0 or cpar != 0.0:
        a1, a2, a3 = body_drag(v1, v2, v3, cxy * rotor_plane_scale(u0, m * g, e), cz, cpar)
        out[at] = out[at] + a1 / m
        out[at + 1] = out[at + 1] + a2 / m
        out[at + 2] = out[at + 2] + a3 / m
    out[at + 3] = q * r * (jy - jz) / jx + u1 / jx
    out[at + 4] = p * r * (jz - jx) / jy + u2 / jy
    out[at + 5] = p * q * (jx - jy) / jz + u3 / jz


@njit
def _add_force(x, force, out):
    """``out[6:9]`` += :math:`R^T a`: the external acceleration a = ``force[:3]`` (NED, m/s^2)
    in the body frame."""
    b0, b1, b2 = mtv(rpy_matrix(x[3], x[4], x[5]), force[0], force[1], force[2])
    out[6] += b0
    out[7] += b1
    out[8] += b2


@njit
def rk4_step(x, u0, u1, u2, u3, force, plant, jx, jy, jz, dt, work):
    """One classical RK4 step of :func:`plant_rhs` from x, in place: the input held, and the
    external acceleration ``force`` = (a_N, a_E, a_D, on) held too (``on`` 0: none);
    ``work`` is scratch: a tuple of five (12,) arrays."""
    k1, k2, k3, k4, y = work
    half, sixth = 0.5 * dt, dt / 6.0
    _rhs(x, u0, u1, u2, u3, force, plant, jx, jy, jz, k1)
    for j in range(12):
        y[j] = x[j] + half * k1[j]
    _rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k2)
    for j in range(12):
        y[j] = x[j] + half * k2[j]
    _rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k3)
    for j in range(12):
        y[j] = x[j] + dt * k3[j]
    _rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k4)
    for j in range(12):
        x[j] = x[j] + sixth * (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j])


@njit
def _rhs(x, u0, u1, u2, u3, force, plant, jx, jy, jz, out):
    """:func:`plant_rhs`, and the external acceleration when ``force[3]`` is not 0."""
    plant_rhs(x, u0, u1, u2, u3, plant, jx, jy, jz, out)
    if force[3] != 0.0:
        _add_force(x, force, out)


@njit
def _so3_rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, out):
    """y' of y = (p, R row-major, v, w) (18,): p' = R v, R' = R hat(w), the body dynamics
    (:func:`body_rhs`) and ``force`` as in :func:`rk4_step`."""
    v1, v2, v3, p, q, r = y[12], y[13], y[14], y[15], y[16], y[17]
    R = y[3:12]
    out[0], out[1], out[2] = mv(R, v1, v2, v3)
    for i in range(3):                            # R hat(w), row by row
        a, b, c = y[3 + 3 * i], y[4 + 3 * i], y[5 + 3 * i]
        out[3 + 3 * i] = b * r - c * q
        out[4 + 3 * i] = -a * r + c * p
        out[5 + 3 * i] = a * q - b * p
    body_rhs(y[9], y[10], y[11], v1, v2, v3, p, q, r, u0, u1, u2, u3, plant, jx, jy, jz, out, 12)
    if force[3] != 0.0:
        b0, b1, b2 = mtv(R, force[0], force[1], force[2])
        out[12] += b0
        out[13] += b1
        out[14] += b2


@njit
def rk4_so3_step(y, u0, u1, u2, u3, force, plant, jx, jy, jz, dt, work):
    """One RK4 step, in place, of y = (p, R row-major, v, w) (18,) with the attitude as a
    rotation matrix, then R brought back to SO(3) by one Newton step of the polar
    decomposition, R (3 I - R^T R) / 2 (:class:`mavreg.sim.plant_step.So3Step`'s numpy step,
    the reference); ``force`` as in :func:`rk4_step`, ``work`` five (18,) arrays of scratch."""
    k1, k2, k3, k4, z = work
    _so3_rhs(y, u0, u1, u2, u3, force, plant, jx, jy, jz, k1)
    for j in range(18):
        z[j] = y[j] + 0.5 * dt * k1[j]
    _so3_rhs(z, u0, u1, u2, u3, force, plant, jx, jy, jz, k2)
    for j in range(18):
        z[j] = y[j] + 0.5 * dt * k2[j]
    _so3_rhs(z, u0, u1, u2, u3, force, plant, jx, jy, jz, k3)
    for j in range(18):
        z[j] = y[j] + dt * k3[j]
    _so3_rhs(z, u0, u1, u2, u3, force, plant, jx, jy, jz, k4)
    for j in range(18):
        y[j] = y[j] + (k1[j] + 2.0 * (k2[j] + k3[j]) + k4[j]) * (dt / 6.0)
    R = y[3:12]
    M = mtm(R, R)
    for j in range(9):                        # 3 I - R^T R
        z[j] = (3.0 if j % 4 == 0 else 0.0) - M[j]
    P = mm(R, z)
    for j in range(9):
        y[3 + j] = P[j] / 2.0


plant_rhs_compiled = plant_rhs
"""The former name (the kernel is compiled where numba is)."""


@njit
def angular_acceleration(jx, jy, jz, wx, wy, wz, g1, g2, g3):
    r""":math:`J^{-1}(\gamma - \omega \times J\omega)` of the body rates (eqs 12-14), in the
    form the state predictor's integration uses (:mod:`mavreg.control.estimation.predictor_kernel`)."""
    return (g1 + (jy - jz) * wy * wz) / jx, (g2 + (jz - jx) * wx * wz) / jy, (g3 + (jx - jy) * wx * wy) / jz
