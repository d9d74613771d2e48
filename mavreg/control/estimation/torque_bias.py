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

import math

import numpy as np

from ...accel import njit
from ...config.disturbance import TorqueBiasParams
from ...config.vehicle import VehicleParams
from ...model.mixer_kernel import torques_first, yaw_then_lift

__all__ = ["TorqueBiasObserver", "update", "rotor_wrench", "allocate_less_bias", "bias_n_m", "bias_vector_n_m", "allocated_less_bias", "THETA", "APPLIED",
           "Q_PER_S", "RATE", "LO", "HI", "ROWS", "GATE_CHI2", "SKIPPED", "REJECTED", "UPDATED"]

THETA, APPLIED, Q_PER_S, RATE, LO, HI = range(6)
ROWS = 6
"""Rows of ``kf`` (ROWS, 6), each over (t0 x, y, z, t1 x, y, z): the estimate and its
rate-limited follower (updated in place), then the constants: the random walks' intensities,
the follower's rate bounds, the estimate's bounds."""
GATE_CHI2 = 36.0
"""As the force part's: 6 sigma (Mahalanobis, here over the three axes)."""
SKIPPED, REJECTED, UPDATED = 0, 1, 2
_PASSES = 4
"""Allocations at most per command (:func:`allocate_less_bias`): where the allocation moves the
collective, each pass shrinks the bias's error by about t1 dT/dtau (a few per cent on the
MK-Quadro): at the barrel roll's exit four leave 3e-6 N m of its 0.04 N m."""
_THRUST_TOL_N = 1e-6


@njit
def bias_n_m(tb, thrust_n, axis):
    """The torque bias ``t0 + t1 T`` about ``axis`` (0, 1, 2) of ``tb`` (6,) at collective ``thrust_n``."""
    return tb[axis] + tb[3 + axis] * thrust_n


@njit
def rotor_wrench(u, tb, thrust_n, out):
    """``out`` (4,) = the wrench ``u`` (4,) the rotors must give when the airframe adds the
    torque bias ``tb`` (6,) at the collective ``thrust_n``: the torques less the bias."""
    out[0] = u[0]
    for a in range(3):
        out[1 + a] = u[1 + a] - bias_n_m(tb, thrust_n, a)


@njit
def allocate_less_bias(minv, u, fmax, tb, torques_first_alloc, f):
    """Rotor forces ``f`` (4,) for the wrench ``u`` (4,) on an airframe that adds the torque
    bias ``tb`` (6,): the allocation (:func:`~mavreg.model.mixer_kernel.torques_first`, else
    :func:`~mavreg.model.mixer_kernel.yaw_then_lift`; ``minv`` row-major) of ``u`` less the
    bias at the collective the rotors give. That is ``u[0]`` unless the allocation moves the
    collective (a rotor would pull: all four are lifted; one would pass ``fmax``): then the
    bias is taken again at the collective allocated (a negative collective asked for at the
    barrel roll's exit is flown at a positive one)."""
    want = np.empty(4)
    thrust = max(u[0], 0.0)
    for attempt in range(_PASSES):
        rotor_wrench(u, tb, thrust, want)
        if torques_first_alloc:
            torques_first(minv, want, fmax, f)
        else:
            yaw_then_lift(minv, want, fmax, f)
        given = f[0] + f[1] + f[2] + f[3]
        if abs(given - thrust) <= _THRUST_TOL_N:
            break
        thrust = given


@njit
def update(kf, P, dt, inv_j, r, thrust, y0, y1, y2):
    """One measurement: rate innovation ``(y0, y1, y2)`` (rad/s) over ``dt`` with the mean
    collective ``thrust`` (N); ``inv_j`` (3,) the design's 1/J per axis, ``r`` the measurement
    variance. ``P`` (3, 3): per axis the covariance's (00, 01, 11). Returns :data:`SKIPPED`
    (a non-finite innovation), :data:`REJECTED` (the gate) or :data:`UPDATED`."""
    if not (math.isfinite(y0) and math.isfinite(y1) and math.isfinite(y2) and math.isfinite(thrust)):
        return SKIPPED
    ys = (y0, y1, y2)
    chi2 = 0.0
    for a in range(3):
        P[a, 0] += kf[Q_PER_S, a] * dt
        P[a, 2] += kf[Q_PER_S, 3 + a] * dt
        g = dt * inv_j[a]
        h0, h1 = g, g * thrust
        s = h0 * h0 * P[a, 0] + 2.0 * h0 * h1 * P[a, 1] + h1 * h1 * P[a, 2] + r
        chi2 += ys[a] * ys[a] / s
    if chi2 > GATE_CHI2:
        return REJECTED
    for a in range(3):
        g = dt * inv_j[a]
        h0, h1 = g, g * thrust
        p00, p01, p11 = P[a, 0], P[a, 1], P[a, 2]
        ph0 = p00 * h0 + p01 * h1               # P H^T
        ph1 = p01 * h0 + p11 * h1
        s = h0 * ph0 + h1 * ph1 + r
        k0, k1 = ph0 / s, ph1 / s
        kf[THETA, a] = min(max(kf[THETA, a] + k0 * ys[a], kf[LO, a]), kf[HI, a])
        kf[THETA, 3 + a] = min(max(kf[THETA, 3 + a] + k1 * ys[a], kf[LO, 3 + a]), kf[HI, 3 + a])
        # Joseph form: (I - K H) P (I - K H)^T + r K K^T
        a00, a01 = 1.0 - k0 * h0, -k0 * h1
        a10, a11 = -k1 * h0, 1.0 - k1 * h1
        b00, b01 = a00 * p00 + a01 * p01, a00 * p01 + a01 * p11
        b10, b11 = a10 * p00 + a11 * p01, a10 * p01 + a11 * p11
        P[a, 0] = b00 * a00 + b01 * a01 + r * k0 * k0
        P[a, 1] = b00 * a10 + b01 * a11 + r * k0 * k1
        P[a, 2] = b10 * a10 + b11 * a11 + r * k1 * k1
    for j in range(6):
        step = kf[RATE, j] * dt
        d = kf[THETA, j] - kf[APPLIED, j]
        kf[APPLIED, j] += min(max(d, -step), step)
    return UPDATED


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
    for _ in range(_PASSES):
        want[1:] = u[1:] - bias_vector_n_m(torque_bias, thrust)
        f = allocate(mixer_inverse, want, max_rotor_thrust_n)
        given = float(f.sum())
        if abs(given - thrust) <= _THRUST_TOL_N:
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
