"""The published state estimate: the truth, a little late, with correlated errors (sans-I/O).

Once per control period (dt) the estimator turns the true state of ``latency`` ago into
what the vehicle publishes:

- position and velocity (NED): true + e, each axis a first-order Gauss-Markov process
  with the exact discretization ``e_{k+1} = a e_k + sigma sqrt(1 - a^2) n_k``,
  ``a = exp(-dt / tau)``, ``n_k ~ N(0, 1)``; stationary SD sigma, autocorrelation
  ``exp(-lag / tau)``. Each process starts from its stationary distribution;
- attitude: ``q_est = q_true * exp(dtheta / 2)``, a small rotation ``dtheta`` (rad, body
  frame), each axis a Gauss-Markov process as above;
- body rates (the gyro): true + b + w, the bias b a slow Gauss-Markov process, w white
  noise of SD ``gyro_noise_sd_rad_s`` per published sample.

Normal numbers come from ``numpy.random.default_rng([seed, 6])`` in chunks, 15 per
period (3 position, 3 velocity, 3 attitude, 3 bias, 3 white), whichever SDs are zero.
"""
from __future__ import annotations

import math

import numpy as np

from .physics import quat_mul
from .world import EstimatorParams

__all__ = ["Estimator", "gauss_markov_coefficients"]

_CHUNK = 1024
_PER_PERIOD = 15


def gauss_markov_coefficients(sd: float, tau_s: float, dt_s: float) -> tuple[float, float]:
    """``(a, c)`` of the exact discretization ``e_{k+1} = a e_k + c n_k`` of a Gauss-Markov process.

    Raises
    ------
    ValueError
        If ``tau_s`` is not positive.
    """
    if not (tau_s > 0.0 and math.isfinite(tau_s)):
        raise ValueError(f"Gauss-Markov correlation time must be > 0, got {tau_s!r}")
    a = math.exp(-dt_s / tau_s)
    return a, sd * math.sqrt(1.0 - a * a)


class Estimator:
    """Errors of the published estimate (see the module docstring).

    Parameters
    ----------
    params : EstimatorParams
    dt_s : float
        Control period: one :meth:`publish` per period.
    seed : int
    """

    def __init__(self, params: EstimatorParams, dt_s: float, seed: int):
        self.params = params
        att_sd = math.radians(params.attitude_sd_deg)
        sds = (params.position_sd_m, params.velocity_sd_m_s, att_sd, params.gyro_bias_sd_rad_s)
        taus = (params.position_tau_s, params.velocity_tau_s, params.attitude_tau_s, params.gyro_bias_tau_s)
        coeffs = [gauss_markov_coefficients(sd, tau, dt_s) for sd, tau in zip(sds, taus)]
        self._a = [a for a, _ in coeffs for _ in range(3)]
        self._c = [c for _, c in coeffs for _ in range(3)]
        self.white_sd = float(params.gyro_noise_sd_rad_s)
        self.rng = np.random.default_rng([int(seed), 6])
        # 12 Gauss-Markov states: position xyz, velocity xyz, attitude xyz, gyro bias xyz.
        init = self.rng.standard_normal(12).tolist()
        self.errors = [sd * init[3 * i + j] for i, sd in enumerate(sds) for j in range(3)]
        self._normals: list = []
        self._i = 0

    def _row(self):
        if self._i >= len(self._normals):
            self._normals = self.rng.standard_normal((_CHUNK, _PER_PERIOD)).tolist()
            self._i = 0
        row = self._normals[self._i]
        self._i += 1
        return row

    def publish(self, s) -> tuple:
        """The estimate of true state ``s`` (13-tuple, see :mod:`firmware_sim.physics`).

        Returns ``(position_ned, velocity_ned, quaternion_wxyz, body_rates)`` as tuples,
        then advances the error processes one period.
        """
        e = self.errors
        n = self._row()
        pos = (s[0] + e[0], s[1] + e[1], s[2] + e[2])
        vel = (s[7] + e[3], s[8] + e[4], s[9] + e[5])
        dx, dy, dz = e[6], e[7], e[8]
        angle = math.sqrt(dx * dx + dy * dy + dz * dz)
        q = (s[3], s[4], s[5], s[6])
        if angle > 0.0:
            k = math.sin(0.5 * angle) / angle
            q = quat_mul(q, (math.cos(0.5 * angle), k * dx, k * dy, k * dz))
        w = self.white_sd
        rates = (s[10] + e[9] + w * n[12], s[11] + e[10] + w * n[13], s[12] + e[11] + w * n[14])
        self.errors = [a * x + c * z for a, x, c, z in zip(self._a, e, self._c, n)]
        return pos, vel, q, rates
