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

from ...model.linearize import complex_step_jacobian
from ...model.quadrotor import QuadrotorModel
from ...model.rotation import euler_rates_matrix, rpy_to_matrix, wrap_angle
from ...model.so3 import attitude_error, exp_so3, right_jacobian_inv

__all__ = ["NW", "FrozenAttitude", "transverse_rhs", "transverse_rhs_so3", "transverse_jacobians",
           "transverse_coordinates"]

NW = 11


class FrozenAttitude:
    """The attitude terms of :func:`transverse_rhs` at a zero attitude error, computed once
    per dtype of w and reused by every call whose w has zero attitude columns (the
    linearization's columns that perturb the position, velocity, rates or input: 12 of 15
    calls). They are the very numbers such a call would compute: the same expressions on
    arrays of the same layout."""

    def __init__(self, xbar, Rbar=None):
        self.xbar, self.Rbar = xbar, Rbar
        self._terms: dict = {}

    def terms(self, w):
        """The terms for ``w`` (None where its attitude columns are not all zero)."""
        if np.any(w[:, 2:5]):
            return None
        key = np.dtype(w.dtype).str
        if key not in self._terms:
            self._terms[key] = _attitude_terms(self.xbar, np.zeros(w.shape, dtype=w.dtype), self.Rbar)
        return self._terms[key]


def _attitude_terms(xbar, w, Rbar):
    """(R, W) of the roll-pitch-yaw form, (E, R, J_r^-1) of the SO(3) form, at ``w``."""
    if Rbar is not None:
        E = exp_so3(w[:, 2:5])
        return E, Rbar @ E, right_jacobian_inv(w[:, 2:5])
    x_r = xbar[:, 3:] + w[:, 2:]
    return (rpy_to_matrix(x_r[:, 0], x_r[:, 1], x_r[:, 2]),      # (3,3,N)
            euler_rates_matrix(x_r[:, 0], x_r[:, 1]))


def transverse_rhs(model: QuadrotorModel, F, k, xbar, ubar, dxbar, w, uw, with_sdot: bool = False,
                   Rbar=None, frozen: FrozenAttitude | None = None):
    """F(s, w, u_w) for a batch: F (N,3,3), k (N,2), xbar (N,12), ubar (N,4),
    dxbar (N,12) = x-bar'(s), w (N,11), uw (N,4). Returns (N,11), and ds/dt (N,) too with
    ``with_sdot``. Complex-safe.

    ``Rbar`` (N,3,3), the nominal attitude, selects the SO(3) attitude error
    (:func:`transverse_rhs_so3`); None, the paper's roll-pitch-yaw differences.
    ``frozen``: the attitude terms at zero attitude error of this xbar and Rbar, used when w's
    attitude columns are zero (the same numbers, computed once).
    """
    terms = None if frozen is None else frozen.terms(w)
    if Rbar is not None:
        return transverse_rhs_so3(model, F, k, Rbar, xbar, ubar, dxbar, w, uw, with_sdot, terms)
    x_r = xbar[:, 3:] + w[:, 2:]           # angles, body velocity, body rates
    u = ubar + uw
    R, W = terms if terms is not None else _attitude_terms(xbar, w, None)
    Rv = np.einsum("ijn,nj->ni", R, x_r[:, 3:6])
    t, m1, m2 = F[:, :, 0], F[:, :, 1], F[:, :, 2]
    sdot = np.sum(t * Rv, axis=1) / (1 - k[:, 0] * w[:, 0] - k[:, 1] * w[:, 1])
    # model.f's rows 3..11 (its position rows and its second R left out: the same numbers)
    wb = x_r[:, 6:9].T
    eul = np.einsum("ij...,j...->i...", W, wb)
    vdot, wdot = model.body_derivatives(R[2], x_r[:, 3:6].T, wb, u.T)
    out = np.empty((len(w), NW), dtype=np.result_type(w, uw, float))
    out[:, 0] = np.sum(m1 * Rv, axis=1) / sdot
    out[:, 1] = np.sum(m2 * Rv, axis=1) / sdot
    out[:, 2:5] = eul.T / sdot[:, None] - dxbar[:, 3:6]
    out[:, 5:8] = vdot.T / sdot[:, None] - dxbar[:, 6:9]
    out[:, 8:11] = wdot.T / sdot[:, None] - dxbar[:, 9:12]
    return (out, sdot) if with_sdot else out


def transverse_rhs_so3(model: QuadrotorModel, F, k, Rbar, xbar, ubar, dxbar, w, uw,
                       with_sdot: bool = False, terms=None):
    r"""The transverse dynamics with the attitude error on SO(3): ``w[2:5] = e`` with
    :math:`R = \bar R(s)\,\mathrm{Exp}(e)`.

    The nominal turns at :math:`\bar R' = \bar R\hat{\bar\omega}/\bar v` (its body rates
    over its speed, :math:`\bar v = |\bar v_b|`), so (:mod:`mavreg.model.so3`)

    .. math::
        e' = \frac{1}{\dot s} J_r^{-1}(e)\Big(\omega - \mathrm{Exp}(e)^T\bar\omega
             \frac{\dot s}{\bar v}\Big),

    the position and velocity rows as in :func:`transverse_rhs`; gravity enters the body
    dynamics through :math:`R^T e_3` alone. Defined for every attitude: no roll-pitch-yaw
    kinematics. Complex-safe.
    """
    E, R, Jinv = terms if terms is not None else _attitude_terms(xbar, w, Rbar)
    vb = xbar[:, 6:9] + w[:, 5:8]
    wb = xbar[:, 9:12] + w[:, 8:11]
    Rv = np.einsum("nij,nj->ni", R, vb)
    t, m1, m2 = F[:, :, 0], F[:, :, 1], F[:, :, 2]
    sdot = np.sum(t * Rv, axis=1) / (1 - k[:, 0] * w[:, 0] - k[:, 1] * w[:, 1])
    vbar = np.sqrt(np.sum(xbar[:, 6:9] ** 2, axis=1))
    wnom = np.einsum("nji,nj->ni", E, xbar[:, 9:12]) * (sdot / vbar)[:, None]
    edot = np.einsum("nij,nj->ni", Jinv, wb - wnom)
    vdot, wdot = model.body_derivatives(R[:, 2, :].T, vb.T, wb.T, (ubar + uw).T)
    out = np.empty((len(w), NW), dtype=np.result_type(w, uw, Rbar, float))
    out[:, 0] = np.sum(m1 * Rv, axis=1) / sdot
    out[:, 1] = np.sum(m2 * Rv, axis=1) / sdot
    out[:, 2:5] = edot / sdot[:, None]
    out[:, 5:8] = vdot.T / sdot[:, None] - dxbar[:, 6:9]
    out[:, 8:11] = wdot.T / sdot[:, None] - dxbar[:, 9:12]
    return (out, sdot) if with_sdot else out


def transverse_jacobians(model: QuadrotorModel, F, k, xbar, ubar, dxbar, Rbar=None):
    """A(s) = dF/dw and B(s) = dF/du_w at w = 0, u_w = 0, by complex step (exact to
    machine precision). Returns A (N,11,11), B (N,11,4). ``Rbar``: the SO(3) form."""
    w0 = np.zeros((len(xbar), NW))
    u0 = np.zeros((len(xbar), 4))
    fz = FrozenAttitude(xbar, Rbar)
    A = complex_step_jacobian(lambda w: transverse_rhs(model, F, k, xbar, ubar, dxbar, w, u0, Rbar=Rbar,
                                                       frozen=fz), w0)
    B = complex_step_jacobian(lambda uw: transverse_rhs(model, F, k, xbar, ubar, dxbar, w0, uw, Rbar=Rbar,
                                                        frozen=fz), u0)
    return A, B


def transverse_coordinates(position, frame, c, x, xbar, Rbar=None, R=None):
    """w (11,) of state x at the path point (c, frame) whose nominal is xbar.

    Attitude error: with ``Rbar`` (the nominal attitude), the rotation vector
    Log(Rbar^T R) with R the state's attitude (``R``, or from its roll-pitch-yaw); else the
    roll-pitch-yaw differences wrapped to (-pi, pi].
    """
    d = np.asarray(position) - c
    w = np.empty(NW)
    w[0] = d @ frame[:, 1]
    w[1] = d @ frame[:, 2]
    if Rbar is None:
        w[2:5] = wrap_angle(x[3:6] - xbar[3:6])
    else:
        w[2:5] = attitude_error(Rbar, rpy_to_matrix(*x[3:6]) if R is None else R)
    w[5:] = x[6:] - xbar[6:]
    return w
