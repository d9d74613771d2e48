r"""The airframe's drag: the one home of its maths (numpy reference).

The design model's drag (vehicle file: ``rotor_drag_n_s_per_m`` = :math:`(c_{xy}, c_z)`,
``parasitic_drag_n_s2_per_m2`` = :math:`c_p`) is a linear body-frame drag, the same in the
rotor plane, plus a quadratic parasitic drag, both on the velocity relative to the ground:

.. math::
    D = -R\,C\,R^T v - c_p |v|\, v,\qquad C = \mathrm{diag}(c_{xy}, c_{xy}, c_z),

in NED with :math:`v` the NED velocity and :math:`R` body to NED; in the body frame
:math:`D_b = -C v_b - c_p|v_b|v_b`. With :math:`b_3 = R e_3` the linear part is
:math:`-c_{xy}(v - (b_3\cdot v) b_3) - c_z (b_3\cdot v) b_3`.

The rotor-plane coefficient may grow with the collective thrust :math:`T` (vehicle file:
``rotor_drag_thrust_exponent`` = :math:`e`, default 0):

.. math::
    c_{xy}(T) = c_{xy}\,(T / T_h)^e,\qquad T_h = m g,

the rotors' momentum drag, which grows as the square root of the thrust (:math:`e = 1/2`:
each rotor's induced velocity grows so; ArduPilot's multicopter simulation has it). The file's
:math:`c_{xy}` is then the coefficient in hover. With :math:`e = 0` every form below is the
constant-coefficient model, operation for operation (:func:`rotor_plane_scale` returns 1
without computing anything). Each function below is one of
the forms the code needs; :mod:`mavreg.model.drag_kernel` has the same forms for the
compiled kernels, operation for operation (``tests/unit/test_drag.py`` holds them together
and against each other). The flat nominal (:mod:`mavreg.maneuver.flatness`) feeds the drag's
time derivatives forward as jets of this same model; the disturbance observer's regressors
(:func:`mavreg.control.estimation.disturbance.regressors`) are its derivatives in the coefficients.
The bundled emulator (``firmware_sim``) keeps its own drag on purpose.
"""
from __future__ import annotations

import numpy as np

__all__ = ["body_drag_n", "drag_ned_n", "linear_drag_ned_n", "drag_change_n", "rotor_plane_scale",
           "rotor_plane_scale_jet"]


def rotor_plane_scale(thrust_n, hover_thrust_n: float, exponent: float):
    """:math:`(T / T_h)^e`, the factor on the rotor-plane drag coefficient at collective thrust
    ``thrust_n`` (a number or an array; complex-safe for the complex-step linearization).
    Exactly 1.0 for ``exponent`` 0; 0 where the thrust is not positive."""
    if exponent == 0.0:
        return 1.0
    ratio = np.asarray(thrust_n) / hover_thrust_n
    up = np.real(ratio) > 0.0
    return np.where(up, np.where(up, ratio, 1.0) ** exponent, 0.0)


def rotor_plane_scale_jet(thrust_jet, hover_thrust_n: float, exponent: float):
    """The scale :math:`(T/T_h)^e` and its first two time derivatives from the thrust's
    ``(T, dT/dt, d2T/dt2)`` (arrays of positive T): what the flat nominal feeds forward."""
    r0, r1, r2 = (np.asarray(a, dtype=float) / hover_thrust_n for a in thrust_jet)
    s0 = r0 ** exponent
    return s0, exponent * s0 / r0 * r1, exponent * s0 / r0 * (r2 + (exponent - 1.0) * r1 * r1 / r0)


def body_drag_n(v_body, cxy: float, cz: float, cp: float) -> np.ndarray:
    """The drag force in the body frame, :math:`-C v_b - c_p |v_b| v_b`, for v (3,) or (3, N)
    (complex-safe: the design model's complex-step linearization goes through it)."""
    v1, v2, v3 = v_body[0], v_body[1], v_body[2]
    quad = cp * np.sqrt(v1 * v1 + v2 * v2 + v3 * v3)
    return np.array([-(cxy + quad) * v1, -(cxy + quad) * v2, -(cz + quad) * v3])


def drag_ned_n(R, v_ned, cxy: float, cz: float, cp: float) -> np.ndarray:
    """The drag force in NED, :math:`-R C R^T v - c_p |v| v` (R (3, 3), v (3,))."""
    R = np.asarray(R, dtype=float)
    v = np.asarray(v_ned, dtype=float)
    return R @ body_drag_n(R.T @ v, cxy, cz, cp)


def linear_drag_ned_n(b3, v_ned, cxy: float, cz: float) -> np.ndarray:
    """The linear drag in NED from the body z axis ``b3`` (3,):
    :math:`-c_{xy}(v - (b_3\\cdot v) b_3) - c_z (b_3\\cdot v) b_3`."""
    v = np.asarray(v_ned, dtype=float)
    along = float(b3 @ v)
    return -cxy * (v - along * b3) - cz * along * b3


def drag_change_n(R, v_ned, sigma: float, cxy: float, cz: float, cp: float) -> np.ndarray:
    """The drag at velocity :math:`\\sigma v` less the drag at v (NED, attitude R): what the
    speed governor's re-timing changes."""
    C = R @ np.diag((cxy, cxy, cz)) @ R.T
    speed = float(np.linalg.norm(v_ned))
    return -(sigma - 1.0) * (C @ v_ned) - cp * speed * v_ned * (sigma * abs(sigma) - 1.0)
