r"""The torque part of the disturbance observer: a body torque the design model does not know.

The torque model
----------------
On top of the design model's torques (eq 34 of the rotor forces), the airframe feels, per
body axis :math:`a`,

.. math::
    \tau_{b,a} = t_{0,a} + t_{1,a}\,T,

with :math:`T` the rotors' collective thrust. A centre-of-mass offset :math:`r` is exactly
:math:`t_1 = -(r \times e_3)` (the thrust's arm); rotors of unequal thrust give, to first order
in their spread, torques proportional to the collective (each rotor near :math:`T/4`); the
constant :math:`t_0` (off by default) covers anything independent of the thrust. In a hover
the collective hardly varies, so :math:`t_0` and :math:`t_1` cannot be told apart there,
while :math:`t_1` alone is observable as soon as the rotors lift: it is the part estimated by
default (:class:`~mavreg.config.disturbance.TorqueBiasParams`).

The filter
----------
Its measurement is the body rate of each sample against the design model's prediction from
the previous sample (:class:`~mavreg.control.estimation.predictor.StatePredictor`, which already
integrates the commands that acted and the current estimate):
:math:`\omega_k - \hat\omega_k = \frac{h}{J_a}(\delta t_0 + \delta t_1 T) + \text{noise}` per
axis (the gyroscopic coupling of an error is second order over one period). Three
independent two-state Kalman filters (random walks), the same gate as the force part's (a
measurement more than 6 sigma from its prediction over the three axes is refused and
counted), the estimate clipped to its bounds, and a follower at bounded rates that the
compensation uses.

The compensation
----------------
The estimate is a torque the airframe adds to whatever the rotors give: the regulator and
the hover controller ask the rotors for their wrench less it, at the collective the
allocation gives (:func:`allocate_less_bias`), and read the wrench the rotors achieve plus it. The collective is untouched, so nothing that
compares commanded with measured thrust sees it.

Pure: numbers in, numbers out. The update is one scalar kernel (:func:`update`), compiled
by numba where it is installed (:func:`mavreg.accel.njit`), plain Python otherwise.
"""
from __future__ import annotations


import numpy as np

from ...config.disturbance import TorqueBiasParams
from ...config.vehicle import VehicleParams
from .torque_bias_kernel import (APPLIED, GATE_CHI2, HI, LO, PASSES, Q_PER_S, RATE, REJECTED, ROWS, SKIPPED,
                                 THETA, THRUST_TOL_N, UPDATED, allocate_less_bias, bias_n_m, rotor_wrench, update)

__all__ = ["TorqueBiasObserver", "update", "rotor_wrench", "allocate_less_bias", "bias_n_m", "bias_vector_n_m", "allocated_less_bias", "THETA", "APPLIED",
           "Q_PER_S", "RATE", "LO", "HI", "ROWS", "GATE_CHI2", "SKIPPED", "REJECTED", "UPDATED"]

def bias_vector_n_m(torque_bias, thrust_n: float) -> np.ndarray:
    """(3,) the torque bias ``t0 + t1 T`` of ``torque_bias`` (6,) at collective ``thrust_n``
    (numpy; :func:`bias_n_m` per axis in the kernels)."""
    tb = np.asarray(torque_bias, dtype=float)
    return tb[:3] + tb[3:] * float(thrust_n)


def allocated_less_bias(allocate, mixer_inverse, u, max_rotor_thrust_n: float, torque_bias) -> np.ndarray:
    """:func:`allocate_less_bias` in numpy, with an allocation policy of :mod:`mavreg.model.mixer`
    (``allocate(mixer_inverse, u, max_rotor_thrust_n)``)."""
    u = np.asarray(u, dtype=float)
    want = u.copy()
    thrust = max(float(u[0]), 0.0)
    for _ in range(PASSES):
        want[1:] = u[1:] - bias_vector_n_m(torque_bias, thrust)
        f = allocate(mixer_inverse, want, max_rotor_thrust_n)
        given = float(f.sum())
        if abs(given - thrust) <= THRUST_TOL_N:
            break
        thrust = given
    return f


class TorqueBiasObserver:
    """Kalman filters on the airframe's torque bias (see the module docstring).

    Parameters
    ----------
    params : TorqueBiasParams
    vehicle : VehicleParams
        The design's inertia (the measurement's scale).
    """

    def __init__(self, params: TorqueBiasParams, vehicle: VehicleParams):
        self.params = p = params
        self._inv_j = np.array([1.0 / float(j) for j in vehicle.inertia_kg_m2])
        sd = np.array([p.constant_sd_n_m] * 3 + [p.per_thrust_sd_m] * 3)
        self._kf = np.zeros((ROWS, 6))
        self._kf[Q_PER_S] = sd ** 2 / p.tau_s
        self._kf[RATE] = [p.max_constant_rate_n_m_per_s] * 3 + [p.max_per_thrust_rate_m_per_s] * 3
        hi = np.array([p.max_constant_n_m] * 3 + [p.max_per_thrust_m] * 3)
        self._kf[LO], self._kf[HI] = -hi, hi
        self._P0 = np.column_stack([sd[:3] ** 2, np.zeros(3), sd[3:] ** 2])
        self._r = p.rate_noise_rad_s ** 2
        self.P = np.empty((3, 3))
        """Per axis the covariance of (t0, t1): its (00, 01, 11)."""
        self.theta = self._kf[THETA]
        """The estimate (t0 x, y, z in N m; t1 x, y, z in m), a view."""
        self.theta_applied = self._kf[APPLIED]
        """Its follower at bounded rates (what the compensation uses), a view."""
        self.updates = 0
        self.rejected = 0
        """Measurements refused by the innovation gate."""
        self.reset()

    def reset(self) -> None:
        """No bias, with the initial uncertainty."""
        self.theta[:] = 0.0
        self.theta_applied[:] = 0.0
        self.P[:] = self._P0

    def update(self, dt_s: float, thrust_n: float, innovation_rad_s, rate_rad_s=(0.0, 0.0, 0.0)) -> bool:
        """One measurement: ``innovation_rad_s`` (3,) = the sample's body rates ``rate_rad_s``
        less their prediction from the previous sample ``dt_s`` earlier, the mean collective
        over the interval ``thrust_n`` (physical N). Not learned while the rate is above
        ``learning_max_rate_rad_s``. Returns whether the estimate changed."""
        w0, w1, w2 = rate_rad_s
        if w0 * w0 + w1 * w1 + w2 * w2 > self.params.learning_max_rate_rad_s ** 2:
            return False
        y0, y1, y2 = innovation_rad_s
        status = update(self._kf, self.P, float(dt_s), self._inv_j, self._r, float(thrust_n), float(y0),
                        float(y1), float(y2))
        if status == REJECTED:
            self.rejected += 1
        elif status == UPDATED:
            self.updates += 1
        return status == UPDATED
