r"""Rotor lag in the transverse linearization: the state augmented with the achieved wrench.

Real rotors do not produce the commanded force at once: each follows its command with a
first-order lag of time constant :math:`\tau` (20-50 ms for brushless motors with 10-inch
propellers). With the same :math:`\tau` on every rotor the lag commutes with the mixer of
eq 34, so the wrench :math:`u_a = (f, \gamma)` the rotors actually produce obeys
:math:`\dot u_a = (u_c - u_a)/\tau` for the commanded wrench :math:`u_c`.

The nominal command that makes the lagged wrench follow :math:`\bar u(s)` is
:math:`\bar u + \tau\,\dot{\bar u} = \bar u + \tau v \bar u'(s)` (the feedforward lead of
:class:`~mavreg.control.controllers.regulator.ManeuverRegulator`). With :math:`a = u_a - \bar u(s)` and
:math:`u_c = \bar u + \tau v \bar u' + \nu`, :math:`\dot a = \dot u_a - \bar u'\dot s`, and in s

.. math::
    a' = \frac{\tau v \bar u' + \nu - a}{\tau \dot s(w)} - \bar u'(s),\qquad
    w' = F(s, w, a),

where :math:`F` is the transverse system of :mod:`~mavreg.control.design.transverse` driven by the
*achieved* wrench deviation. At :math:`(w, a, \nu) = 0`, :math:`\dot s = v` and the right
side vanishes. The linearization in :math:`z = (w, a) \in \mathbb R^{15}` and :math:`\nu`
keeps :math:`\dot s(w)`:

.. math::
    A_z = \begin{bmatrix} A & B \\ -\bar u' \,\partial_w \dot s / v & -I/(\tau v)\end{bmatrix},
    \qquad B_z = \begin{bmatrix} 0 \\ I/(\tau v)\end{bmatrix}.

An LQR on :math:`(A_z, B_z)` knows that its command acts through the lag, instead of assuming
an instantaneous wrench and only leading the feedforward.
"""
from __future__ import annotations

import numpy as np

from ...model.linearize import complex_step_jacobian
from ...model.quadrotor import QuadrotorModel
from ...model.rotor_lag import lag_augment
from .transverse import NW, FrozenAttitude, transverse_rhs

__all__ = ["NZ", "augmented_rhs", "augmented_jacobians", "lag_augment", "lag_loop_factor"]

NZ = NW + 4


def augmented_rhs(model: QuadrotorModel, tau_s: float, F, k, xbar, ubar, dxbar, dubar, speed,
                  z, nu, Rbar=None, frozen=None):
    """z' for a batch: z (N,15) = (w, a), nu (N,4) commanded wrench deviation, dubar (N,4)
    = u-bar'(s), speed (N,) nominal v(s). Returns (N,15). Complex-safe. ``Rbar``: the SO(3)
    attitude error (:func:`~mavreg.control.design.transverse.transverse_rhs`)."""
    w, a = z[:, :NW], z[:, NW:]
    wdot, sdot = transverse_rhs(model, F, k, xbar, ubar, dxbar, w, a, with_sdot=True, Rbar=Rbar,
                                frozen=frozen)
    lead = tau_s * speed[:, None] * dubar
    adot = (lead + nu - a) / (tau_s * sdot[:, None]) - dubar
    return np.concatenate([wdot, adot], axis=1)


def augmented_jacobians(model: QuadrotorModel, tau_s: float, F, k, xbar, ubar, dxbar, dubar, speed,
                        Rbar=None):
    """A_z (N,15,15) and B_z (N,15,4) at z = 0, nu = 0, by complex step."""
    if not tau_s > 0:
        raise ValueError(f"the rotor time constant must be positive, got {tau_s}")
    z0 = np.zeros((len(xbar), NZ))
    n0 = np.zeros((len(xbar), 4))
    args = (model, tau_s, F, k, xbar, ubar, dxbar, dubar, speed)
    fz = FrozenAttitude(xbar, Rbar)        # the attitude terms of the 16 of 19 columns that keep it
    A = complex_step_jacobian(lambda z: augmented_rhs(*args, z, n0, Rbar, fz), z0)
    B = complex_step_jacobian(lambda nu: augmented_rhs(*args, z0, nu, Rbar, fz), n0)
    return A, B


def lag_loop_factor(K, decay: float) -> float:
    r"""How much of a command the feedback on the achieved wrench answers within one control
    period: :math:`\max_s \rho(K_a(s))\,(1 - e^{-T/\tau})`, with :math:`K_a` the gains on the
    achieved wrench (the last four columns of K (N, 4, 15)) and ``decay`` :math:`e^{-T/\tau}`.

    The design is continuous; a zero-order hold of period T makes the achieved wrench at the
    next command :math:`(1 - e^{-T/\tau})` of this one, which that feedback answers with
    :math:`-K_a` times it. Well above 1 that alone grows from command to command, alternating
    at the Nyquist rate (measured on ArduCopter at 200 Hz: factor 2.1 with a design lag of
    8 ms oscillated within 50 ms; 1.1 and 0.6 at 20 ms flew; the rest of the loop damps some).
    0 for gains without the lag (K (N, 4, 11))."""
    K = np.asarray(K, dtype=float)
    if K.shape[-1] <= NW:
        return 0.0
    rho = np.abs(np.linalg.eigvals(K[:, :, NW:])).max()
    return float(rho * (1.0 - decay))
