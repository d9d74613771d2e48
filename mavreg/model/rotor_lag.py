r"""The rotors' first-order lag: the one home of its maths (numpy reference).

Each rotor's force :math:`f` follows its command :math:`c` through a first-order lag of time
constant :math:`\tau` (``rotor_time_constant_s``; 0: ideal rotors, :math:`f = c`):

.. math::
    \dot f = (c - f)/\tau .

For a command held over a step :math:`\Delta t` this is exact in closed form:

.. math::
    f(\Delta t) = c + (f - c)\,e^{-\Delta t/\tau},\qquad
    \frac{1}{\Delta t}\int_0^{\Delta t} f = c + (f - c)\,\frac{\tau}{\Delta t}(1 - e^{-\Delta t/\tau}),

the second the force's mean over the step (what a physics step should apply). The compiled
kernels use the same maths, operation for operation, from :mod:`mavreg.model.rotor_lag_kernel`;
``tests/unit/test_rotor_lag.py`` holds the two together. The lag in the transverse
linearization (s-domain, with the nominal's lead) is :mod:`mavreg.control.design.actuator`'s, built
on :func:`lag_augment`'s time-domain form. The bundled emulator (``firmware_sim``) keeps its
own rotor model on purpose (it stands for somebody else's firmware).
"""
from __future__ import annotations

import numpy as np

__all__ = ["lag_decay", "mean_fraction", "lag_toward", "lag_rate", "lag_augment"]


def lag_decay(dt_s: float, tau_s: float) -> float:
    r""":math:`e^{-\Delta t/\tau}`, the share of the gap to the command left after ``dt_s``
    (0.0 for ideal rotors, ``tau_s`` <= 0)."""
    return 0.0 if tau_s <= 0 else float(np.exp(-dt_s / tau_s))


def mean_fraction(dt_s: float, tau_s: float, decay: float) -> float:
    r""":math:`\frac{\tau}{\Delta t}(1 - e^{-\Delta t/\tau})`, the share of the gap left on
    average over the step (``decay`` = :func:`lag_decay`; 0.0 for ideal rotors)."""
    return 0.0 if decay == 0.0 else tau_s / dt_s * (1.0 - decay)


def lag_toward(forces_n, commands_n, share):
    r"""``commands + (forces - commands) * share``: the forces after a step with ``share`` =
    :func:`lag_decay`, or their mean over it with ``share`` = :func:`mean_fraction`."""
    return commands_n + (forces_n - commands_n) * share


def lag_rate(forces_n, commands_n, tau_s: float):
    r""":math:`\dot f = (c - f)/\tau`, the continuous form (``tau_s`` > 0)."""
    return (commands_n - forces_n) / tau_s


def lag_augment(A, B, tau_s: float) -> tuple[np.ndarray, np.ndarray]:
    r"""A time-domain plant ``x' = A x + B u`` (A (n, n), B (n, m)) driven through the rotor lag:
    the state ``(x, a)`` with ``a' = (u_c - a)/tau``,

    .. math::
        A_z = \begin{bmatrix} A & B \\ 0 & -I/\tau \end{bmatrix},\qquad
        B_z = \begin{bmatrix} 0 \\ I/\tau \end{bmatrix}.

    This is :func:`mavreg.control.design.actuator.augmented_jacobians` times the speed where the
    nominal input does not change (u-bar' = 0: a hover, a steady line), for a plant given in
    time."""
    if not tau_s > 0:
        raise ValueError(f"the rotor time constant must be positive, got {tau_s}")
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    n, m = B.shape
    Az = np.block([[A, B], [np.zeros((m, n)), -np.eye(m) / tau_s]])
    Bz = np.vstack([np.zeros((n, m)), np.eye(m) / tau_s])
    return Az, Bz
