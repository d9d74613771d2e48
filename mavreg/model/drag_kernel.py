r"""The airframe's drag for the compiled kernels (:func:`mavreg.accel.njit`): the forms of
:mod:`mavreg.model.drag`, on scalars, R a row-major 9-tuple (body to NED)."""
from __future__ import annotations

import math

from ..accel import njit
from .rotation_kernel import mtv, mv

__all__ = ["body_drag", "drag_ned", "linear_drag_and_force", "drag_change", "rotor_plane_scale"]


@njit
def rotor_plane_scale(thrust, hover_thrust, exponent):
    """:func:`mavreg.model.drag.rotor_plane_scale` of a float: (T / T_h)^e, 1.0 for e = 0."""
    if exponent == 0.0:
        return 1.0
    ratio = thrust / hover_thrust
    return ratio ** exponent if ratio > 0.0 else 0.0


@njit
def body_drag(v1, v2, v3, cxy, cz, cp):
    """:func:`mavreg.model.drag.body_drag_n` of the body velocity (v1, v2, v3)."""
    quad = cp * math.sqrt(v1 * v1 + v2 * v2 + v3 * v3)
    return -(cxy + quad) * v1, -(cxy + quad) * v2, -(cz + quad) * v3


@njit
def drag_ned(R, vx, vy, vz, cxy, cz, cp):
    """Drag force (NED) at velocity v: -R C R^T v - c_p |v| v, C = diag(c_xy, c_xy, c_z)
    (:func:`mavreg.model.drag.drag_ned_n`)."""
    zx, zy, zz = R[2], R[5], R[8]
    along = (cz - cxy) * (zx * vx + zy * vy + zz * vz)
    q = cxy + cp * math.sqrt(vx * vx + vy * vy + vz * vz)
    return -q * vx - along * zx, -q * vy - along * zy, -q * vz - along * zz


@njit
def linear_drag_and_force(R, v0, v1, v2, cxy, cz, fx, fy, fz):
    """The linear drag (NED) at attitude R and NED velocity v plus a constant force
    (:func:`mavreg.model.drag.linear_drag_ned_n` plus f)."""
    along = R[2] * v0 + R[5] * v1 + R[8] * v2
    return (-cxy * (v0 - along * R[2]) - cz * along * R[2] + fx,
            -cxy * (v1 - along * R[5]) - cz * along * R[5] + fy,
            -cxy * (v2 - along * R[8]) - cz * along * R[8] + fz)


@njit
def drag_change(R, v0, v1, v2, sigma, cxy, cz, parasitic):
    """The modelled drag at NED velocity sigma v less the drag at v (attitude R)
    (:func:`mavreg.model.drag.drag_change_n`)."""
    b0, b1, b2 = mtv(R, v0, v1, v2)
    c0, c1, c2 = mv(R, cxy * b0, cxy * b1, cz * b2)
    speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    q = parasitic * speed * (sigma * abs(sigma) - 1.0)
    return (-(sigma - 1.0) * c0 - q * v0, -(sigma - 1.0) * c1 - q * v1, -(sigma - 1.0) * c2 - q * v2)
