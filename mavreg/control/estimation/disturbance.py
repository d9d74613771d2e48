r"""What the design model does not know about the airframe, estimated in flight and compensated.

The force model
---------------
On top of the design model (eqs 6-17 with the vehicle file's drag and thrust calibration),
the airframe feels

.. math::
    \Delta F = -\delta c_{xy}\,(v - (b_3^T v)\,b_3) - \delta c_z\,(b_3^T v)\,b_3 + F_w
               - \delta k\,T\,b_3,

with :math:`b_3 = R e_3` the body z axis (NED), :math:`v` the velocity, :math:`T` the
commanded rotor thrust: a linear drag beyond the file's (:math:`\delta c_{xy}, \delta c_z`),
a constant force (:math:`F_w`: the steady part of a wind, a payload) and a thrust scale
error :math:`\delta k` (a sagging battery). A steady wind :math:`v_w` is the drag of the
air-relative velocity, :math:`-C (v - v_w) = -C v + C v_w`: drag plus a constant force.
The model is linear in :math:`\theta = (c_{xy}, c_z, F_w, k)`: a drag that turns with the
vehicle through a loop is six numbers that stay constant, where a force estimate would
have to chase it (a world-frame force observer lagged the loop's drag and made it worse).

The filter
----------
A Kalman filter on :math:`\theta` (random walks). Its measurement is the velocity of each
sample against the design model's prediction from the previous sample with the current
estimate and the commands that acted in between (:class:`~mavreg.control.estimation.predictor.StatePredictor`):
:math:`v_k - \hat v_k = \frac{h}{m}\,\Phi_{k-1}(\theta - \hat\theta) + \text{noise}`, with
:math:`\Phi` the regressors above. The estimate is clipped to bounds, and a measurement more than 6 sigma from its prediction
(a telemetry stall, a bump) is refused and counted.

The compensation
----------------
Where a disturbance :math:`d` acts, the nominal's force :math:`-\bar T \bar R e_3` is kept by
thrusting :math:`u = \bar T \bar R e_3 + d` instead: thrust :math:`|u|` along a body z axis
turned by the smallest rotation onto :math:`u/|u|` (:func:`compensated_nominal`). The
regulator then regulates about that attitude; the velocity along the path is untouched,
so the compensation never makes the vehicle catch up with anything.

Pure: numbers in, numbers out.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...accel import use_compiled
from ...config.disturbance import DisturbanceParams
from ...config.vehicle import G, VehicleParams
from ...model.drag import linear_drag_ned_n, rotor_plane_scale
from ...model.rotation import matrix_to_rpy, rpy_to_matrix, wrap_angle
from ...model.so3 import log_so3
from . import observer_kernel as ok
from .lag_observer import RotorLagObserver
from .torque_bias import TorqueBiasObserver

__all__ = ["DisturbanceEstimate", "DisturbanceObserver", "compensated_nominal", "compensate", "regressors"]


@dataclass(frozen=True)
class DisturbanceEstimate:
    """The airframe's force model as estimated (totals, not corrections)."""

    drag_n_s_per_m: tuple[float, float]
    """Linear body drag (c_xy, c_z)."""
    force_ned_n: tuple[float, float, float]
    """Constant external force."""
    thrust_scale: float
    """Thrust per unit commanded."""
    torque_bias: tuple[float, ...] = (0.0,) * 6
    """The airframe's torque bias ``(t0 x, y, z (N m), t1 x, y, z (m))``: ``t0 + t1 T`` per body
    axis at collective ``T`` (:mod:`mavreg.control.estimation.torque_bias`; zeros without its estimate)."""

    def extra_force_ned(self, R, v, base_drag_n_s_per_m) -> np.ndarray:
        """The force the design model with drag ``base_drag_n_s_per_m`` misses, at attitude
        ``R`` and velocity ``v`` (NED), excluding the thrust scale (the commands carry it)."""
        dcxy = self.drag_n_s_per_m[0] - base_drag_n_s_per_m[0]
        dcz = self.drag_n_s_per_m[1] - base_drag_n_s_per_m[1]
        return linear_drag_ned_n(np.asarray(R)[:, 2], v, dcxy, dcz) + np.asarray(self.force_ned_n)


def regressors(R, v, thrust_n: float, xy_scale: float = 1.0) -> np.ndarray:
    """:math:`\\Phi` (3, 6): the force (NED) per unit of (c_xy, c_z, F_n, F_e, F_d, k), at
    attitude ``R``, velocity ``v`` and commanded thrust ``thrust_n``; ``xy_scale`` the
    rotor-plane drag's factor at that thrust (:func:`mavreg.model.drag.rotor_plane_scale`:
    c_xy is then the coefficient in hover)."""
    b3 = np.asarray(R, dtype=float)[:, 2]
    v = np.asarray(v, dtype=float)
    along = float(b3 @ v)
    phi = np.empty((3, 6))
    phi[:, 0] = -xy_scale * (v - along * b3)
    phi[:, 1] = -along * b3
    phi[:, 2:5] = np.eye(3)
    phi[:, 5] = -thrust_n * b3
    return phi


_GATE_CHI2 = ok.GATE_CHI2
"""Innovation gate: a measurement farther than 6 sigma (Mahalanobis, 3 dof) from the
prediction is refused (probability under the filter's own model: 1e-7)."""


class DisturbanceObserver:
    """Kalman filter on the airframe's force model (see the module docstring).

    Parameters
    ----------
    params : DisturbanceParams
    vehicle : VehicleParams
        Mass, and the file's drag and thrust calibration (the initial estimate).
    compiled : bool, optional
        Update by the compiled kernel (:mod:`mavreg.control.estimation.observer_kernel`, the same
        results to rounding) or by the numpy update, the reference. None (default):
        compiled where numba is (:data:`mavreg.accel.ACCELERATED`).
    """

    def __init__(self, params: DisturbanceParams, vehicle: VehicleParams, compiled: bool | None = None):
        self.compiled = use_compiled(compiled, "observer")
        self.params = params
        self.mass_kg = float(vehicle.mass_kg)
        self.base_drag = tuple(float(c) for c in vehicle.rotor_drag_n_s_per_m)
        self._drag_scale = (float(vehicle.mass_kg) * G, float(vehicle.rotor_drag_thrust_exponent))
        self._theta0 = np.array([*self.base_drag, 0.0, 0.0, 0.0, float(vehicle.thrust_scale)])
        p = params
        sd = np.array([p.drag_sd_n_s_per_m] * 2 + [p.force_sd_n] * 2 + [p.vertical_force_sd_n]
                      + [p.thrust_scale_sd])
        tau = np.array([p.drag_tau_s] * 2 + [p.force_tau_s] * 3 + [p.thrust_scale_tau_s])
        self._P0 = np.diag(sd ** 2)
        self._q_per_s = sd ** 2 / tau                 # wanders by sd over tau
        self._r = p.velocity_noise_m_s ** 2
        hi_c, hi_f = p.max_drag_n_s_per_m, p.max_force_n
        self._rate = np.array([p.max_drag_rate_n_s_per_m_per_s] * 2 + [p.max_force_rate_n_per_s] * 3
                              + [p.max_thrust_scale_rate_per_s])
        self._lo = np.array([0.0, 0.0, -hi_f, -hi_f, -hi_f, p.thrust_scale_bounds[0]])
        self._hi = np.array([hi_c, hi_c, hi_f, hi_f, hi_f, p.thrust_scale_bounds[1]])
        # The compiled update's layout: theta and theta_applied are views of its first rows.
        self._kf = np.zeros((ok.ROWS, 6))
        self._kf[ok.Q_PER_S], self._kf[ok.RATE] = self._q_per_s, self._rate
        self._kf[ok.LO], self._kf[ok.HI] = self._lo, self._hi
        self.theta = self._kf[ok.THETA]
        self.theta_applied = self._kf[ok.APPLIED]
        self.P = np.empty((6, 6))
        self.updates = 0
        self.rejected = 0
        """Measurements refused by the innovation gate."""
        self.torque = (TorqueBiasObserver(params.torque_bias, vehicle)
                       if params.torque_bias.enabled and vehicle.output == "rotors" else None)
        """The torque part (:mod:`mavreg.control.estimation.torque_bias`), or None. Not with rates and
        thrust to an autopilot (``vehicle.output`` "rates"): the autopilot's rate loop
        integrates its rate error, so a torque proportional to the thrust is rejected there,
        and what the body rates show against the model is the loop's own transient. On a stock
        PX4 (SIH) the part read that as t1 = +23.9 mm and the hold drifted 0.54 m off its point
        (docs/autopilots.md, *PX4*)."""
        self.lag = (RotorLagObserver(params.rotor_lag, vehicle)
                    if params.rotor_lag.enabled and vehicle.output == "rotors" else None)
        """The rotor-lag part (:mod:`mavreg.control.estimation.lag_observer`), or None. Not with rates and
        thrust to an autopilot (``vehicle.output`` "rates"): there the wrench's lag is the one
        the output realizes and the autopilot's rate loop, identified in the vehicle file; the
        estimate read the rate loop as 36 ms of rotor lag and the barrel roll's loop went from
        3.0 to 3.9 cm."""
        self.reset()

    def reset(self) -> None:
        """Back to the vehicle file's model, with the initial uncertainty."""
        self.theta[:] = self._theta0
        self.theta_applied[:] = self._theta0
        self.P[:] = self._P0
        if self.torque is not None:
            self.torque.reset()
        if self.lag is not None:
            self.lag.reset()
        self._estimates = None

    @staticmethod
    def _as_estimate(th, torque=None) -> DisturbanceEstimate:
        return DisturbanceEstimate((float(th[0]), float(th[1])), (float(th[2]), float(th[3]), float(th[4])),
                                   float(th[5]), (0.0,) * 6 if torque is None else tuple(torque.tolist()))

    def _both(self) -> tuple[DisturbanceEstimate, DisturbanceEstimate]:
        """(estimate, applied), made once per measurement (read several times a sample)."""
        if self._estimates is None:
            tq = self.torque
            self._estimates = (self._as_estimate(self.theta, None if tq is None else tq.theta),
                               self._as_estimate(self.theta_applied, None if tq is None else tq.theta_applied))
        return self._estimates

    @property
    def estimate(self) -> DisturbanceEstimate:
        """The filter's estimate (what predictions use)."""
        return self._both()[0]

    @property
    def applied(self) -> DisturbanceEstimate:
        """The estimate followed at bounded rates (what the compensation uses)."""
        return self._both()[1]

    def update_torque(self, dt_s: float, thrust_n: float, innovation_rad_s, rate_rad_s) -> None:
        """One measurement of the torque part (:meth:`TorqueBiasObserver.update
        <mavreg.control.estimation.torque_bias.TorqueBiasObserver.update>`); nothing without it."""
        if self.torque is not None and 0.0 < dt_s <= self.params.max_sample_gap_s:
            if self.torque.update(dt_s, thrust_n, innovation_rad_s, rate_rad_s):
                self._estimates = None

    def sample_gap(self) -> None:
        """Samples too far apart to compare: the rotor-lag part's sensitivity starts again
        (:meth:`RotorLagObserver.restart <mavreg.control.estimation.lag_observer.RotorLagObserver.restart>`)."""
        if self.lag is not None:
            self.lag.restart()

    def update_lag(self, dt_s: float, torque_change_n_m, innovation_rad_s, rate_rad_s) -> None:
        """One sample interval of the rotor-lag part (:meth:`RotorLagObserver.update
        <mavreg.control.estimation.lag_observer.RotorLagObserver.update>`); nothing without it."""
        if self.lag is not None and 0.0 < dt_s <= self.params.max_sample_gap_s:
            self.lag.update(dt_s, torque_change_n_m, innovation_rad_s, rate_rad_s)

    def update(self, dt_s: float, R, v, thrust_n: float, innovation_m_s) -> None:
        """One measurement: ``innovation_m_s`` (3,) = the sample's velocity less its prediction
        from the previous sample ``dt_s`` earlier (attitude ``R``, velocity ``v``, commanded
        thrust ``thrust_n`` over the interval), predicted with the current estimate."""
        if not (0.0 < dt_s <= self.params.max_sample_gap_s):
            return
        xy_scale = float(rotor_plane_scale(thrust_n, *self._drag_scale))
        if self.compiled:
            y0, y1, y2 = innovation_m_s
            v0, v1, v2 = v
            status = ok.update(self._kf, self.P, float(dt_s), self.mass_kg, self._r,
                               self.params.drag_learning_min_speed_m_s,
                               self.params.thrust_scale_learning_max_axial_speed_m_s, np.asarray(R, dtype=float),
                               float(v0), float(v1), float(v2), float(thrust_n), float(y0), float(y1), float(y2),
                               xy_scale)
            if status == ok.REJECTED:
                self.rejected += 1
            elif status == ok.UPDATED:
                self._estimates = None
                self.updates += 1
            return
        y = np.asarray(innovation_m_s, dtype=float)
        if not np.all(np.isfinite(y)):
            return
        self.P += np.diag(self._q_per_s * dt_s)
        H = (dt_s / self.mass_kg) * regressors(R, v, thrust_n, xy_scale)  # (3, 6)
        p = self.params
        if float(np.linalg.norm(v)) < p.drag_learning_min_speed_m_s:
            H[:, 0:2] = 0.0                  # drag unobservable (and biased) at low speed
        if abs(float(np.asarray(R, dtype=float)[:, 2] @ np.asarray(v, dtype=float))) > \
                p.thrust_scale_learning_max_axial_speed_m_s:
            H[:, 5] = 0.0                    # the thrust scale and the axial drag look alike
        S = H @ self.P @ H.T + self._r * np.eye(3)
        if float(y @ np.linalg.solve(S, y)) > _GATE_CHI2:
            self.rejected += 1           # an outlier (a telemetry stall, a bump): not a force
            return
        K = np.linalg.solve(S, H @ self.P).T                            # (6, 3)
        self.theta[:] = np.clip(self.theta + K @ y, self._lo, self._hi)
        I_KH = np.eye(6) - K @ H
        self.P[:] = I_KH @ self.P @ I_KH.T + self._r * (K @ K.T)          # Joseph form
        step = self._rate * dt_s
        self.theta_applied += np.clip(self.theta - self.theta_applied, -step, step)
        self._estimates = None
        self.updates += 1


def _turned(R: np.ndarray, thrust_n: float, force_ned, max_turn_rad: float = math.pi) -> tuple[np.ndarray, float]:
    """(R', T'): the attitude turned by the smallest rotation that aligns the body z axis with
    ``u = thrust_n R e3 + force_ned``, and ``|u|``. A turn larger than ``max_turn_rad`` stops
    there, with ``u`` projected on the turned body z axis. (Keeping the nominal's x axis
    projected on the new rotor plane instead flew a crosswind's run-out worse: 16 cm against
    2 cm.)"""
    b3 = R[:, 2]
    u = thrust_n * b3 + np.asarray(force_ned, dtype=float)
    T = float(np.linalg.norm(u))
    if T < 1e-9:
        return R, thrust_n
    n = u / T
    axis = np.cross(b3, n)
    s, c = float(np.linalg.norm(axis)), float(b3 @ n)
    if s <= 1e-12:
        return R, T
    k = axis / s
    capped = math.atan2(s, c) > max_turn_rad
    if capped:
        s, c = math.sin(max_turn_rad), math.cos(max_turn_rad)
    Kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R2 = (np.eye(3) + s * Kx + (1.0 - c) * (Kx @ Kx)) @ R           # Rodrigues
    return R2, (float(u @ R2[:, 2]) if capped else T)


def compensated_nominal(xbar, thrust_n: float, force_ned, xbar_ahead=None, thrust_ahead_n: float = 0.0,
                        force_ahead_ned=None, dt_s: float = 0.0,
                        max_turn_rad: float = math.pi) -> tuple[np.ndarray, float]:
    """The nominal state and thrust that keep the nominal's force when ``force_ned`` acts too.

    The thrust vector becomes :math:`u = \\bar T \\bar R e_3 + d`; the body z axis turns by
    the smallest rotation onto :math:`u/|u|` (:func:`_turned`); the body velocity is the nominal's NED velocity
    in the turned body frame. Given the nominal ``dt_s`` ahead (``xbar_ahead``,
    ``thrust_ahead_n``, ``force_ahead_ned``), the rates gain the turn's own rate, the
    difference of the compensated and the nominal attitude's finite-difference rates
    (without it, a compensation that turns with the path, as a drag does through a loop,
    is a rate error the regulator fights); else they are kept.

    Parameters
    ----------
    xbar : (12,) array_like
        Nominal state (position, roll-pitch-yaw, body velocity, body rates).
    thrust_n : float
        Nominal collective thrust.
    force_ned : (3,) array_like
        The extra force to cancel.
    max_turn_rad : float
        Largest turn of the attitude; past it the force is cancelled only in part (the
        regulator's gains hold near the attitude they were designed at).

    Returns
    -------
    (xbar', thrust')
    """
    xbar = np.asarray(xbar, dtype=float)
    R_ahead = None if xbar_ahead is None else rpy_to_matrix(*np.asarray(xbar_ahead, dtype=float)[3:6])
    out, T, _ = compensate(xbar, rpy_to_matrix(*xbar[3:6]), thrust_n, force_ned, R_ahead,
                           thrust_ahead_n, force_ahead_ned, dt_s, max_turn_rad)
    return out, T


def compensate(xbar, R, thrust_n: float, force_ned, R_ahead=None, thrust_ahead_n: float = 0.0,
               force_ahead_ned=None, dt_s: float = 0.0,
               max_turn_rad: float = math.pi) -> tuple[np.ndarray, float, np.ndarray]:
    """:func:`compensated_nominal` given the nominal attitude ``R`` (and ``R_ahead``, the
    nominal's ``dt_s`` ahead) as rotation matrices, as the SO(3) form keeps them; returns
    the turned attitude too: ``(xbar', thrust', R')``."""
    xbar = np.asarray(xbar, dtype=float)
    R2, T = _turned(R, thrust_n, force_ned, max_turn_rad)
    out = xbar.copy()
    out[3:6] = xbar[3:6] + wrap_angle(matrix_to_rpy(R2) - xbar[3:6])      # stay on xbar's branch
    out[6:9] = R2.T @ (R @ xbar[6:9])
    if R_ahead is not None and dt_s > 0.0:
        Ra2, _ = _turned(R_ahead, thrust_ahead_n, force_ahead_ned, max_turn_rad)
        out[9:12] = xbar[9:12] + (log_so3(R2.T @ Ra2) - log_so3(R.T @ R_ahead)) / dt_s
    return out, T, R2
