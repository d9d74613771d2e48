r"""The hover controller's step (:meth:`mavreg.control.controllers.hover.HoverController.step`) as two kernels.

:func:`reference` evaluates the ramp (its degree-7 polynomials and their first three
derivatives, or the hold past its end) and turns its acceleration, less an estimated
disturbance force, into the attitude and thrust that give it (exact, the drag taken at the
attitude it tilts, three passes), its velocity into that body frame, its jerk into
small-angle rates; :func:`feedback` forms ``u = u_ref - K (x - x_ref)`` (yaw error
wrapped, the velocity error in the reference's body frame) and the rotor forces (:func:`~mavreg.control.controllers.step_kernel.yaw_then_lift`). Between
the two, the caller picks the gain for the reference's yaw (cached per yaw).

Plain floats, compiled by numba (:func:`mavreg.accel.njit`) where available; the numpy step
of :class:`~mavreg.control.controllers.hover.HoverController` stays the reference
(``tests/unit/test_hover_kernel.py`` holds the two together).

``ref`` (16,): x_ref (12), u_ref (4). ``out`` (20,): u (4), rotor forces (4), error (12).
``ramp`` (6,): duration, end position (3), end yaw, and 0 (unused); ``end_v`` (3,).
"""
from __future__ import annotations

import math

from ...accel import njit
from ...config.vehicle import G
from ...model.drag_kernel import linear_drag_and_force as extra_force
from ...model.rotation_kernel import mtv, mv, rpy_matrix, wrap
from ..estimation.torque_bias import allocate_less_bias

__all__ = ["reference", "feedback", "REF_SIZE", "OUT_SIZE", "MIN_TILT_COS"]

MIN_TILT_COS = 0.5
"""The tilt compensation's cosine is bounded below by this (60 deg): at most twice the thrust."""

REF_SIZE = 16
OUT_SIZE = 20


@njit
def _poly(c, row, t, order):
    """The ``order``-th derivative of sum_k c[row, k] t^k at ``t``, as numpy's
    ``hover._poly_eval_many`` forms it (each term, then the sum)."""
    acc = 0.0
    for k in range(order, 8):
        fall = 1.0
        for i in range(order):
            fall *= k - i
        acc += fall * t ** (k - order) * c[row, k]
    return acc


@njit
def _attitude_for(ax, ay, az, yaw):
    """(roll, pitch, thrust per unit mass, R) whose thrust gives acceleration ``a`` at ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    fx, fy, fz = ax, ay, az - G
    thrust = math.sqrt(fx * fx + fy * fy + fz * fz)
    b0, b1, b2 = -fx / thrust, -fy / thrust, -fz / thrust
    h0, h1 = c * b0 + s * b1, -s * b0 + c * b1
    roll = math.asin(min(max(-h1, -1.0), 1.0))
    pitch = math.atan2(h0, b2)
    return roll, pitch, thrust, rpy_matrix(roll, pitch, yaw)


@njit
def reference(ref, coeffs, t, ramp, end_v, has_dist, dcxy, dcz, dfx, dfy, dfz, mass):
    """x_ref and u_ref of the ramp at ramp time ``t`` into ``ref`` (see the module docstring);
    with ``has_dist``, the estimate's drag ``(dcxy, dcz)`` and force ``(dfx, dfy, dfz)`` fed
    forward."""
    duration = ramp[0]
    if t >= duration:
        dt = t - duration
        px, py, pz = ramp[1] + end_v[0] * dt, ramp[2] + end_v[1] * dt, ramp[3] + end_v[2] * dt
        vx, vy, vz = end_v[0], end_v[1], end_v[2]
        ax = ay = az = jx = jy = 0.0
        yaw, yaw_rate = ramp[4], 0.0
    else:
        tt = max(t, 0.0)
        px, py, pz = _poly(coeffs, 0, tt, 0), _poly(coeffs, 1, tt, 0), _poly(coeffs, 2, tt, 0)
        vx, vy, vz = _poly(coeffs, 0, tt, 1), _poly(coeffs, 1, tt, 1), _poly(coeffs, 2, tt, 1)
        ax, ay, az = _poly(coeffs, 0, tt, 2), _poly(coeffs, 1, tt, 2), _poly(coeffs, 2, tt, 2)
        jx, jy = _poly(coeffs, 0, tt, 3), _poly(coeffs, 1, tt, 3)
        yaw, yaw_rate = _poly(coeffs, 3, tt, 0), _poly(coeffs, 3, tt, 1)
    roll, pitch, thrust, R = _attitude_for(ax, ay, az, yaw)
    if has_dist:
        for _ in range(3):
            dx, dy, dz = extra_force(R, vx, vy, vz, dcxy, dcz, dfx, dfy, dfz)
            roll, pitch, thrust, R = _attitude_for(ax - dx / mass, ay - dy / mass, az - dz / mass, yaw)
    c, s = math.cos(yaw), math.sin(yaw)
    jb0, jb1 = c * jx + s * jy, -s * jx + c * jy
    ref[0], ref[1], ref[2] = px, py, pz
    ref[3], ref[4], ref[5] = roll, pitch, yaw
    ref[6], ref[7], ref[8] = mtv(R, vx, vy, vz)
    ref[9], ref[10], ref[11] = jb1 / G, -jb0 / G, yaw_rate
    ref[12], ref[13], ref[14], ref[15] = mass * thrust, 0.0, 0.0, 0.0


@njit
def feedback(out, x, ref, K, Minv, fmax, tb):
    """u = u_ref - K e, e = x - x_ref (angles wrapped; the velocity error taken in the
    reference's body frame, :meth:`~mavreg.control.controllers.hover.HoverController.error`), the
    collective divided by the cosine of the tilt from the reference
    (:meth:`~mavreg.control.controllers.hover.HoverController.tilt_compensated`), and the rotor forces of
    u less the torque bias ``tb`` (6,) (:func:`~mavreg.control.estimation.torque_bias.allocate_less_bias`),
    into ``out``."""
    for i in range(12):
        e = x[i] - ref[i]
        out[8 + i] = wrap(e) if 3 <= i < 6 else e
    R = rpy_matrix(x[3], x[4], x[5])
    Rr = rpy_matrix(ref[3], ref[4], ref[5])
    vn = mv(R, x[6], x[7], x[8])
    vb = mtv(Rr, vn[0], vn[1], vn[2])
    out[14], out[15], out[16] = vb[0] - ref[6], vb[1] - ref[7], vb[2] - ref[8]
    for r in range(4):
        acc = 0.0
        for i in range(12):
            acc += K[r, i] * out[8 + i]
        out[r] = ref[12 + r] - acc
    out[0] /= max(R[2] * Rr[2] + R[5] * Rr[5] + R[8] * Rr[8], MIN_TILT_COS)
    allocate_less_bias(Minv, out[0:4], fmax, tb, False, out[4:8])
