r"""Transverse coordinates and their s-domain dynamics (paper eqs 25-32, corrected).

With the path frame :math:`(t, m_1, m_2)` at the projected arc length s, the position is
:math:`y = c(s) + w_1 m_1 + w_2 m_2`. Differentiating and using the rotation-minimizing
frame equations :math:`t' = k_1 m_1 + k_2 m_2`, :math:`m_i' = -k_i t`:

.. math::
    \dot s = \frac{t^T R v}{1 - k_1 w_1 - k_2 w_2},\qquad
    \dot w_1 = m_1^T R v,\qquad \dot w_2 = m_2^T R v .

(The paper's eq 30 is the Serret-Frenet special case: there :math:`k_2 = 0` and the frame
twists at the torsion, adding :math:`\pm\tau\dot s w`.) For the other nine coordinates
:math:`w_{i-1} = x_i - \bar x_i(s)`, :math:`\dot w_{i-1} = f_i(x, u) - \bar x_i'(s)\dot s`.
Dividing by :math:`\dot s` gives the transverse system in s,

.. math::
    w' = F(s, w, u_w) = \Big(\frac{m_1^T R v}{\dot s}, \frac{m_2^T R v}{\dot s},
          \frac{f_{4..12}(\bar x + w, \bar u + u_w)}{\dot s} - \bar x'_{4..12}(s)\Big).

Eq 32 as printed ends in :math:`-\bar x_i'\dot s`; dividing eq 31 by :math:`\dot s` leaves
:math:`-\bar x_i'`. And :math:`\dot s` depends on w (through R, v and the :math:`1-k\cdot w`
factor), which the linearization keeps. At w = 0, u_w = 0, F = 0 exactly when the nominal
satisfies :math:`\bar x' = f(\bar x, \bar u)/v`.
"""
from __future__ import annotations

import numpy as np

from ..model.linearize import complex_step_jacobian
from ..model.quadrotor import QuadrotorModel
from ..model.rotation import rpy_to_matrix, wrap_angle

__all__ = ["NW", "transverse_rhs", "transverse_jacobians", "transverse_coordinates"]

NW = 11


def transverse_rhs(model: QuadrotorModel, F, k, xbar, ubar, dxbar, w, uw, with_sdot: bool = False):
    """F(s, w, u_w) for a batch: F (N,3,3), k (N,2), xbar (N,12), ubar (N,4),
    dxbar (N,12) = x-bar'(s), w (N,11), uw (N,4). Returns (N,11), and ds/dt (N,) too with
    ``with_sdot``. Complex-safe."""
    x_r = xbar[:, 3:] + w[:, 2:]           # angles, body velocity, body rates
    u = ubar + uw
    R = rpy_to_matrix(x_r[:, 0], x_r[:, 1], x_r[:, 2])   # (3,3,N)
    Rv = np.einsum("ijn,nj->ni", R, x_r[:, 3:6])
    t, m1, m2 = F[:, :, 0], F[:, :, 1], F[:, :, 2]
    sdot = np.sum(t * Rv, axis=1) / (1 - k[:, 0] * w[:, 0] - k[:, 1] * w[:, 1])
    x = np.concatenate([np.zeros((len(w), 3), dtype=x_r.dtype), x_r], axis=1)
    fr = model.f(x.T, u.T).T[:, 3:]
    out = np.empty((len(w), NW), dtype=np.result_type(w, uw, float))
    out[:, 0] = np.sum(m1 * Rv, axis=1) / sdot
    out[:, 1] = np.sum(m2 * Rv, axis=1) / sdot
    out[:, 2:] = fr / sdot[:, None] - dxbar[:, 3:]
    return (out, sdot) if with_sdot else out


def transverse_jacobians(model: QuadrotorModel, F, k, xbar, ubar, dxbar):
    """A(s) = dF/dw and B(s) = dF/du_w at w = 0, u_w = 0, by complex step (exact to
    machine precision). Returns A (N,11,11), B (N,11,4)."""
    w0 = np.zeros((len(xbar), NW))
    u0 = np.zeros((len(xbar), 4))
    A = complex_step_jacobian(lambda w: transverse_rhs(model, F, k, xbar, ubar, dxbar, w, u0), w0)
    B = complex_step_jacobian(lambda uw: transverse_rhs(model, F, k, xbar, ubar, dxbar, w0, uw), u0)
    return A, B


def transverse_coordinates(position, frame, c, x, xbar):
    """w (11,) of state x at the path point (c, frame) whose nominal is xbar.

    Angle errors are wrapped to (-pi, pi].
    """
    d = np.asarray(position) - c
    w = np.empty(NW)
    w[0] = d @ frame[:, 1]
    w[1] = d @ frame[:, 2]
    w[2:5] = wrap_angle(x[3:6] - xbar[3:6])
    w[5:] = x[6:] - xbar[6:]
    return w
