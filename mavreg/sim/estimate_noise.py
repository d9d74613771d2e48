r"""Estimator-grade errors on the design model's state: what a controller really sees.

A flight controller reads an EKF estimate, not the truth. Its errors are correlated in
time (the filter smooths its sensors), so each is a first-order Gauss-Markov process,
discretized exactly at the sample period :math:`\Delta`:

.. math::
    e_{k+1} = a\,e_k + \sigma\sqrt{1 - a^2}\;n_k,\qquad a = e^{-\Delta/\tau},\quad n_k\sim N(0, 1),

stationary with standard deviation :math:`\sigma` and correlation time :math:`\tau`. Position
and velocity errors are NED; the attitude error is a small rotation in the body frame
(:math:`R_{est} = R\exp(\hat e)`); the gyro adds a slow Gauss-Markov bias and white noise
to the body rates. The defaults are those of firmware_sim's ``realistic`` preset (a
motion-capture-aided EKF; docs/firmware_sim.md gives the sources), so a design-model run
and a SITL flight see the same kind of errors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model.rotation import matrix_to_rpy, rpy_to_matrix

__all__ = ["EstimateNoise", "EstimateCorruptor"]


@dataclass(frozen=True)
class EstimateNoise:
    """Standard deviations and correlation times of the estimate's errors."""

    position_sd_m: float = 0.005
    position_tau_s: float = 0.5
    velocity_sd_m_s: float = 0.02
    velocity_tau_s: float = 0.2
    attitude_sd_rad: float = math.radians(0.3)
    attitude_tau_s: float = 0.5
    gyro_sd_rad_s: float = 0.005
    """White noise per sample."""
    gyro_bias_sd_rad_s: float = 0.003
    gyro_bias_tau_s: float = 30.0

    def scaled(self, factor: float) -> "EstimateNoise":
        """Every standard deviation times ``factor`` (0: a perfect estimate)."""
        return EstimateNoise(self.position_sd_m * factor, self.position_tau_s,
                             self.velocity_sd_m_s * factor, self.velocity_tau_s,
                             self.attitude_sd_rad * factor, self.attitude_tau_s,
                             self.gyro_sd_rad_s * factor, self.gyro_bias_sd_rad_s * factor,
                             self.gyro_bias_tau_s)


class _GaussMarkov:
    def __init__(self, sd: float, tau_s: float, dt_s: float, rng: np.random.Generator):
        self.a = math.exp(-dt_s / tau_s)
        self.b = sd * math.sqrt(1.0 - self.a * self.a)
        self.rng = rng
        self.e = sd * rng.standard_normal(3)      # start in the stationary distribution

    def __call__(self) -> np.ndarray:
        self.e = self.a * self.e + self.b * self.rng.standard_normal(3)
        return self.e


class EstimateCorruptor:
    """Turns true design-model states (12,) into estimates, one call per sample.

    Parameters
    ----------
    noise : EstimateNoise
    sample_period_s : float
    rng : numpy.random.Generator
    """

    def __init__(self, noise: EstimateNoise, sample_period_s: float, rng: np.random.Generator):
        dt = float(sample_period_s)
        self.noise = noise
        self.rng = rng
        self._pos = _GaussMarkov(noise.position_sd_m, noise.position_tau_s, dt, rng)
        self._vel = _GaussMarkov(noise.velocity_sd_m_s, noise.velocity_tau_s, dt, rng)
        self._att = _GaussMarkov(noise.attitude_sd_rad, noise.attitude_tau_s, dt, rng)
        self._bias = _GaussMarkov(noise.gyro_bias_sd_rad_s, noise.gyro_bias_tau_s, dt, rng)

    def __call__(self, x) -> tuple[np.ndarray, np.ndarray]:
        """The estimate of state ``x``: (x_est (12,), R_est (3, 3))."""
        x = np.asarray(x, dtype=float)
        R = rpy_to_matrix(*x[3:6])
        v_ned = R @ x[6:9] + self._vel()
        e = self._att()
        th = float(np.linalg.norm(e))
        K = np.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])
        dR = np.eye(3) + (np.sin(th) / th if th > 0 else 1.0) * K + \
            ((1 - np.cos(th)) / th ** 2 if th > 0 else 0.5) * K @ K
        R_est = R @ dR
        out = np.empty(12)
        out[:3] = x[:3] + self._pos()
        out[3:6] = np.unwrap(np.array([x[3:6], matrix_to_rpy(R_est)]), axis=0)[1]
        out[6:9] = R_est.T @ v_ned
        out[9:12] = x[9:12] + self._bias() + self.noise.gyro_sd_rad_s * self.rng.standard_normal(3)
        return out, R_est
