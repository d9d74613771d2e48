r"""The integration loop of :class:`mavreg.control.estimation.predictor.StatePredictor`, one kernel.

From a sample's state, the rigid body of the design model (eqs 1-4 on rotation matrices) is
stepped to the end of the horizon under the commands that act in it, each step holding the
exact mean of the first-order-lagged rotor force over the step (attitude by the exponential
map at the midpoint rate, position and velocity second order). This runs for every sample
the daemon receives, twice with the disturbance observer (its own prediction from the
previous sample), about ten steps each: as a numba kernel (:func:`mavreg.accel.njit`) a
prediction costs a few microseconds instead of about 100 in Python. With ``MAVREG_PURE=1``
(or without numba) the same function runs as plain Python, the reference
(``tests/unit/test_predictor.py`` holds the two together).

Layouts (plain float arrays, so that nothing is allocated in the loop):

- ``state`` (22,), read and overwritten: R row-major (9), p (3), v NED (3), w body (3), the
  lagged rotor forces f (4);
- ``seg`` (K + 2, 5): row 0 the command in force at the sample, ``(t_s, c1..c4)``; rows 1..K
  the commands that start in the horizon, ``(start_s, c1..c4)``; row K + 1 ``(t_end, ...)``;
- ``prm`` (12,): mass, jx, jy, jz, arm length l, drag-torque ratio k, rotor time constant
  tau, c_xy, c_z (the linear body drag), c_p (parasitic), the longest step, the rotor-plane
  drag's thrust exponent e (c_xy at the step's thrust T is c_xy (T / m g)^e);
- ``out`` (:data:`OUT_SIZE`,) of :func:`predict_into`: the predicted design-model state x
  (12: p, roll pitch yaw, v body, w body), R row-major (9), the rotor forces times the
  thrust scale (4), v NED (3).
"""
from __future__ import annotations


import numpy as np

from ...accel import njit
from ...config.vehicle import G
from ...model.drag_kernel import drag_ned, rotor_plane_scale
from ...model.mixer_kernel import wrench
from ...model.quadrotor_kernel import angular_acceleration
from ...model.rotation_kernel import matrix_rpy, mm, rodrigues
from ...model.rotor_lag_kernel import lag_over4
from .torque_bias import bias_n_m

__all__ = ["integrate", "predict_into", "STATE_SIZE", "PARAM_SIZE", "OUT_SIZE"]

STATE_SIZE = 22
PARAM_SIZE = 12
OUT_SIZE = 28


@njit
def integrate(state, seg, prm, thrust_scale, fx, fy, fz, cxy, cz, tb):
    """Step ``state`` (see the module docstring) from ``seg[0, 0]`` to ``seg[-1, 0]``.

    ``thrust_scale``: actual force per commanded; ``(fx, fy, fz)``: a known external force
    (NED, N); ``cxy``, ``cz``: the linear body drag in use (N s/m); ``tb`` (6,): a known body
    torque bias ``t0 + t1 T`` (:mod:`mavreg.control.estimation.torque_bias`). Returns the number of
    steps taken."""
    m, jx, jy, jz, l, k, tau = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6]
    cp, max_step, drag_exponent = prm[9], prm[10], prm[11]
    has_drag = cxy != 0.0 or cz != 0.0 or cp != 0.0
    R = (state[0], state[1], state[2], state[3], state[4], state[5], state[6], state[7], state[8])
    px, py, pz = state[9], state[10], state[11]
    vx, vy, vz = state[12], state[13], state[14]
    wx, wy, wz = state[15], state[16], state[17]
    f0, f1, f2, f3 = state[18], state[19], state[20], state[21]
    c0, c1, c2, c3 = seg[0, 1], seg[0, 2], seg[0, 3], seg[0, 4]
    last = seg.shape[0] - 1
    t = seg[0, 0]
    steps = 0
    for i in range(1, last + 1):
        start = seg[i, 0]
        while t < start - 1e-12:
            dt = min(max_step, start - t)
            # rotor lag: the forces after dt and their mean over it
            f0, f1, f2, f3, m0, m1, m2, m3 = lag_over4(f0, f1, f2, f3, c0, c1, c2, c3, dt, tau)
            if thrust_scale != 1.0:
                m0, m1, m2, m3 = thrust_scale * m0, thrust_scale * m1, thrust_scale * m2, thrust_scale * m3
            # one step of eqs 1-4 with the mean force held
            T, g1, g2, g3 = wrench(l, k, m0, m1, m2, m3)
            g1, g2, g3 = g1 + bias_n_m(tb, T, 0), g2 + bias_n_m(tb, T, 1), g3 + bias_n_m(tb, T, 2)
            d0x, d0y, d0z = angular_acceleration(jx, jy, jz, wx, wy, wz, g1, g2, g3)
            hx, hy, hz = wx + 0.5 * dt * d0x, wy + 0.5 * dt * d0y, wz + 0.5 * dt * d0z
            dmx, dmy, dmz = angular_acceleration(jx, jy, jz, hx, hy, hz, g1, g2, g3)
            R1 = mm(R, rodrigues(hx * dt, hy * dt, hz * dt))
            s = T / m
            a0x, a0y, a0z = -s * R[2] + fx / m, -s * R[5] + fy / m, G - s * R[8] + fz / m
            a1x, a1y, a1z = -s * R1[2] + fx / m, -s * R1[5] + fy / m, G - s * R1[8] + fz / m
            if has_drag:       # both at the step's start velocity
                cxy_t = cxy * rotor_plane_scale(T, m * G, drag_exponent)
                dx, dy, dz = drag_ned(R, vx, vy, vz, cxy_t, cz, cp)
                a0x, a0y, a0z = a0x + dx / m, a0y + dy / m, a0z + dz / m
                dx, dy, dz = drag_ned(R1, vx, vy, vz, cxy_t, cz, cp)
                a1x, a1y, a1z = a1x + dx / m, a1y + dy / m, a1z + dz / m
            q = dt * dt / 6.0
            px, py, pz = (px + dt * vx + q * (2.0 * a0x + a1x), py + dt * vy + q * (2.0 * a0y + a1y),
                          pz + dt * vz + q * (2.0 * a0z + a1z))
            vx, vy, vz = vx + 0.5 * dt * (a0x + a1x), vy + 0.5 * dt * (a0y + a1y), vz + 0.5 * dt * (a0z + a1z)
            wx, wy, wz = wx + dt * dmx, wy + dt * dmy, wz + dt * dmz
            R = R1
            t += dt
            steps += 1
        if i < last:
            c0, c1, c2, c3 = seg[i, 1], seg[i, 2], seg[i, 3], seg[i, 4]
    for j in range(9):
        state[j] = R[j]
    state[9], state[10], state[11] = px, py, pz
    state[12], state[13], state[14] = vx, vy, vz
    state[15], state[16], state[17] = wx, wy, wz
    state[18], state[19], state[20], state[21] = f0, f1, f2, f3
    return steps


@njit
def predict_into(out, R, x, f0, f1, f2, f3, seg, prm, thrust_scale, fx, fy, fz, cxy, cz, tb):
    """From the sample ``x`` (12,) with body-to-NED ``R`` (3, 3) and rotor forces
    ``(f0..f3)`` at ``seg[0, 0]``: :func:`integrate` to ``seg[-1, 0]``, the result into
    ``out`` (see the module docstring). Returns the number of steps taken."""
    state = np.empty(STATE_SIZE)
    for j in range(9):
        state[j] = R[j // 3, j % 3]
    state[9], state[10], state[11] = x[0], x[1], x[2]
    for a in range(3):
        state[12 + a] = R[a, 0] * x[6] + R[a, 1] * x[7] + R[a, 2] * x[8]
    state[15], state[16], state[17] = x[9], x[10], x[11]
    state[18], state[19], state[20], state[21] = f0, f1, f2, f3
    steps = integrate(state, seg, prm, thrust_scale, fx, fy, fz, cxy, cz, tb)
    r = state
    out[0], out[1], out[2] = r[9], r[10], r[11]
    out[3], out[4], out[5] = matrix_rpy((r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]))
    vx, vy, vz = r[12], r[13], r[14]
    out[6] = r[0] * vx + r[3] * vy + r[6] * vz
    out[7] = r[1] * vx + r[4] * vy + r[7] * vz
    out[8] = r[2] * vx + r[5] * vy + r[8] * vz
    out[9], out[10], out[11] = r[15], r[16], r[17]
    for j in range(9):
        out[12 + j] = r[j]
    for j in range(4):
        out[21 + j] = thrust_scale * r[18 + j]
    out[25], out[26], out[27] = vx, vy, vz
    return steps
