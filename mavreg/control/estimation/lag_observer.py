r"""The rotor-lag part of the disturbance observer: the rotors' time constant, learned in flight.

Why
---
The feedforward leads the nominal by the rotors' time constant :math:`\tau` and the
predictor lags the commands by it (:mod:`mavreg.control.controllers.regulator`,
:mod:`mavreg.control.estimation.predictor`). A vehicle file's :math:`\tau` is a guess: brushless motors
and their propellers answer in 10 to 50 ms, and on a barrel roll with 45 ms motors flown on
the file's 20 ms the loop's true error was 6.5 cm, against 2.8 cm with the true value in the
lead and the prediction (and the same gains: the gain schedule is not what the lag costs).

The measurement
---------------
The body rates of each sample against their prediction from the previous sample
(:class:`~mavreg.control.estimation.forecast.Forecaster`) carry the torque the model's rotor forces
miss. Where the true time constant is :math:`\tau + \delta`, the rotors' forces are, to first
order, :math:`f + \delta\,g` with :math:`g = \partial f/\partial\tau` the sensitivity of the
lag filter :math:`\dot f = (c - f)/\tau`, itself a lag of :math:`-\dot f`:

.. math::
    \dot g = -\frac{g + \dot f}{\tau}, \qquad
    \omega_k - \hat\omega_k = \delta\, J^{-1} \int_{t_{k-1}}^{t_k} M_\tau\, g\, dt + \text{noise}.

It is kept on the model's torques (:math:`M_\tau g`, linear), with :math:`\dot f` constant over
each sample interval, and integrated exactly over it. The measurement is the one the torque
bias's filter takes (:mod:`mavreg.control.estimation.torque_bias`), and their regressors differ: the
bias scales with the collective, the lag with the torques' changes. A pure delay the link
measurement misses has the same first-order signature as a longer lag, and the estimate
takes it too, which is what the lead and the prediction need.

The filter
----------
A scalar Kalman filter on :math:`\tau` itself (the predictor always lags by the current
estimate, so the innovation measures :math:`\tau_{true} - \hat\tau`), a random walk, the
same 6-sigma gate as the other parts (over the three axes), clipped to bounds, and a
follower at a bounded rate that the regulator's lead uses. Learned only while the body rate
is low (:class:`~mavreg.config.disturbance.RotorLagParams`): a hover's rotor commands move
enough to see it, and through a loop the rate innovations are mostly what the file's
inertia gets wrong.

Pure: numbers in, numbers out. The update is one scalar kernel (:func:`update`), compiled by
numba where it is installed (:func:`mavreg.accel.njit`), plain Python otherwise.
"""
from __future__ import annotations

import math

import numpy as np

from ...accel import njit
from ...config.disturbance import RotorLagParams

__all__ = ["RotorLagObserver", "update", "advance_sensitivity", "TAU", "APPLIED", "P", "G0", "SIZE",
           "SKIPPED", "REJECTED", "UPDATED", "PROPAGATED"]

TAU, APPLIED, P = 0, 1, 2
G0 = 3
"""``state`` (SIZE,): the estimate (s), its follower (s), its variance (s^2), then the
sensitivity :math:`M_\\tau g` per body axis (N m per second of time constant)."""
SIZE = 6
GATE_CHI2 = 36.0
"""As the force and torque parts': 6 sigma (Mahalanobis, over the three axes)."""
SKIPPED, PROPAGATED, REJECTED, UPDATED = 0, 1, 2, 3


@njit
def advance_sensitivity(state, h, inv_j, dtorque, phi):
    r"""Over one sample interval ``h`` (s) with the model's torque change ``dtorque`` (3,)
    (N m, physical; its slope held over the interval): ``phi`` (3,) = the body-rate change per
    second of time constant, :math:`J^{-1}\int M_\tau g\,dt`, exact for that slope; and the
    sensitivity in ``state`` advanced to the interval's end."""
    tau = state[TAU]
    e = math.exp(-h / tau) if tau > 0.0 else 0.0
    w = tau * (1.0 - e)                  # the integral of e^{-t/tau} over the interval
    for a in range(3):
        slope = dtorque[a] / h
        g = state[G0 + a]
        phi[a] = inv_j[a] * (w * g - slope * (h - w))
        state[G0 + a] = g * e - slope * (1.0 - e)


@njit
def update(state, h, inv_j, dtorque, y, learn, q_per_s, r, lo, hi, rate):
    """One sample interval ``h`` (s): the model's torque change over it ``dtorque`` (3,)
    (N m, physical), the body-rate innovation ``y`` (3,) (rad/s), ``inv_j`` (3,) the design's
    1/J. The sensitivity always advances; the estimate learns only if ``learn``. ``q_per_s``
    the random walk's intensity, ``r`` the innovation's variance per axis, ``lo``/``hi`` the
    bounds, ``rate`` the follower's (s/s). Returns :data:`SKIPPED` (non-finite input; the
    sensitivity restarts), :data:`PROPAGATED` (not learned), :data:`REJECTED` (the gate) or
    :data:`UPDATED`."""
    if not (h > 0.0 and math.isfinite(h)):
        return SKIPPED
    for a in range(3):
        if not (math.isfinite(dtorque[a]) and math.isfinite(y[a])):
            for b in range(3):
                state[G0 + b] = 0.0
            return SKIPPED
    phi = np.empty(3)
    advance_sensitivity(state, h, inv_j, dtorque, phi)
    state[P] += q_per_s * h
    if not learn:
        return PROPAGATED
    pv = state[P]
    pp = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    py = phi[0] * y[0] + phi[1] * y[1] + phi[2] * y[2]
    yy = y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
    s = r + pv * pp
    if (yy - pv * py * py / s) / r > GATE_CHI2:      # y^T (P phi phi^T + r I)^-1 y
        return REJECTED
    state[TAU] = min(max(state[TAU] + pv * py / s, lo), hi)
    state[P] = pv * r / s
    step = rate * h
    d = state[TAU] - state[APPLIED]
    state[APPLIED] += min(max(d, -step), step)
    return UPDATED


class RotorLagObserver:
    """The rotors' time constant, estimated (see the module docstring).

    Parameters
    ----------
    params : RotorLagParams
    vehicle : VehicleParams
        The file's time constant (the initial estimate) and inertia (the measurement's scale).
    """

    def __init__(self, params: RotorLagParams, vehicle):
        self.params = p = params
        self.file_s = float(vehicle.rotor_time_constant_s)
        self._inv_j = np.array([1.0 / float(j) for j in vehicle.inertia_kg_m2])
        self._q = p.sd_s ** 2 / p.tau_s
        self._r = p.rate_noise_rad_s ** 2
        self._lo, self._hi = (float(b) for b in p.bounds_s)
        self.state = np.zeros(SIZE)
        self.updates = 0
        self.rejected = 0
        """Measurements refused by the innovation gate."""
        self.reset()

    @property
    def estimate_s(self) -> float:
        """The estimate (what the prediction lags by)."""
        return float(self.state[TAU])

    @property
    def sd_s(self) -> float:
        """The estimate's standard deviation (the filter's own)."""
        return float(self.state[P]) ** 0.5

    @property
    def applied_s(self) -> float:
        """Its follower at a bounded rate (what the regulator's lead uses)."""
        return float(self.state[APPLIED])

    def reset(self) -> None:
        """Back to the vehicle file's time constant (clipped to the bounds), with the initial
        uncertainty and no sensitivity."""
        self.state[:] = 0.0
        self.state[TAU] = self.state[APPLIED] = min(max(self.file_s, self._lo), self._hi)
        self.state[P] = self.params.sd_s ** 2

    def restart(self) -> None:
        """A gap in the samples: the sensitivity starts again from none (the estimate stays)."""
        self.state[G0:] = 0.0

    def update(self, dt_s: float, torque_change_n_m, innovation_rad_s, rate_rad_s) -> bool:
        """One sample interval ``dt_s``: the model's change of the rotors' torques over it
        (3,), the body-rate innovation (3,) and the sample's body rates (3,). Returns whether
        the estimate changed."""
        w = np.asarray(rate_rad_s, dtype=float)
        learn = float(w @ w) <= self.params.learning_max_rate_rad_s ** 2
        status = update(self.state, float(dt_s), self._inv_j, np.asarray(torque_change_n_m, dtype=float),
                        np.asarray(innovation_rad_s, dtype=float), learn, self._q, self._r, self._lo,
                        self._hi, self.params.max_rate_s_per_s)
        if status == REJECTED:
            self.rejected += 1
        elif status == UPDATED:
            self.updates += 1
        return status == UPDATED
