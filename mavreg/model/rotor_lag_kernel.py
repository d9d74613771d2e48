r"""The rotors' first-order lag for the compiled kernels (:func:`mavreg.accel.njit`): the maths
of :mod:`mavreg.model.rotor_lag`, operation for operation, on scalars (four rotors as
tuples, nothing allocated)."""
from __future__ import annotations

import math

from ..accel import njit

__all__ = ["lag_toward", "lag_toward4", "lag_after4", "lag_over4"]


@njit
def lag_toward(f, c, share):
    """``c + (f - c) * share`` of one rotor (:func:`mavreg.model.rotor_lag.lag_toward`)."""
    return c + (f - c) * share


@njit
def lag_toward4(f0, f1, f2, f3, c0, c1, c2, c3, share):
    """:func:`lag_toward` of four rotors."""
    return c0 + (f0 - c0) * share, c1 + (f1 - c1) * share, c2 + (f2 - c2) * share, c3 + (f3 - c3) * share


@njit
def lag_after4(f0, f1, f2, f3, c0, c1, c2, c3, dt, tau):
    """The four forces after ``dt`` under the held commands (ideal rotors, ``tau`` <= 0:
    the commands)."""
    if tau <= 0.0:
        return c0, c1, c2, c3
    return lag_toward4(f0, f1, f2, f3, c0, c1, c2, c3, math.exp(-dt / tau))


@njit
def lag_over4(f0, f1, f2, f3, c0, c1, c2, c3, dt, tau):
    """The four forces after ``dt`` under the held commands, then their means over it
    (:func:`~mavreg.model.rotor_lag.lag_decay`, :func:`~mavreg.model.rotor_lag.mean_fraction`);
    ideal rotors (``tau`` <= 0) follow the commands at once."""
    if tau <= 0.0:
        return c0, c1, c2, c3, c0, c1, c2, c3
    e = math.exp(-dt / tau)
    frac = tau / dt * (1.0 - e)
    m0, m1, m2, m3 = lag_toward4(f0, f1, f2, f3, c0, c1, c2, c3, frac)
    g0, g1, g2, g3 = lag_toward4(f0, f1, f2, f3, c0, c1, c2, c3, e)
    return g0, g1, g2, g3, m0, m1, m2, m3
