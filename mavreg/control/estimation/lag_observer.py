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

Pure: numbers in, numbers out. The update is one scalar kernel
(:mod:`mavreg.control.estimation.lag_observer_kernel`), compiled by numba where it is installed
(:func:`mavreg.accel.njit`), plain Python otherwise.
"""
from __future__ import annotations


import numpy as np

from ...config.disturbance import RotorLagParams
from .lag_observer_kernel import (APPLIED, G0, P, PROPAGATED, REJECTED, SIZE, SKIPPED, TAU, UPDATED,
                                  advance_sensitivity, update)

__all__ = ["RotorLagObserver", "update", "advance_sensitivity", "TAU", "APPLIED", "P", "G0", "SIZE",
           "SKIPPED", "REJECTED", "UPDATED", "PROPAGATED"]

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
        self._initial_s = float(vehicle.rotor_time_constant_s)
        """The vehicle file's value: the estimate a reset starts from."""
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
        self.state[TAU] = self.state[APPLIED] = min(max(self._initial_s, self._lo), self._hi)
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
