"""The true record of one flown run, and its errors against the plan sample by sample.

Either way a run is flown (design model or emulator), what it leaves is the same
:class:`Flight`: the plant's true position, attitude and velocity, and the rotor forces
commanded and applied, from the start of the maneuver to its end. :func:`truth_trace`
projects each true position on the path (warm-started, as the regulator and
:func:`mavreg.sim.truth.true_errors` do; before the path's start it is its straight
extension) and compares each true attitude with the nominal one at that arc length: the
angle of the rotation between them, as in :mod:`mavreg.sim.truth`. Numpy, the projection
one compiled loop (:meth:`~mavreg.geometry.projection.Projector.series`).
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..geometry.projection import Projector
from ..model.mixer import mixer_matrix
from ..model.rotation import matrix_to_rpy
from ..model.so3 import rotation_angle_deg

__all__ = ["Flight", "Trace", "truth_trace"]


@dataclass(frozen=True)
class Flight:
    """What one run left: K samples in time order, from the maneuver's start (SI, NED)."""

    t_s: np.ndarray
    """(K,) time from the start of the maneuver."""
    position_m: np.ndarray
    """(K, 3) true position."""
    rotation: np.ndarray
    """(K, 3, 3) true body-to-NED rotation."""
    velocity_m_s: np.ndarray
    """(K, 3) true velocity (NED)."""
    rotor_command_n: np.ndarray
    """(K, 4) rotor forces the controller asked for (after its own allocation)."""
    rotor_applied_n: np.ndarray
    """(K, 4) rotor forces that acted (lag, noise, saturation)."""
    status: str
    """``completed`` (the end of the path reached), ``diverged``, ``timeout``, ``failed``
    (the daemon's envelope stopped the maneuver) or ``not_flown``."""
    reason: str
    completed: bool
    saturation_n: float | None
    """The plant's rotor force limit (None: none)."""
    extra: dict
    """Anything the way of flying adds (JSON-ready), e.g. the daemon's envelope peaks."""


@dataclass(frozen=True)
class Trace:
    """Per-sample errors and signals of a :class:`Flight` against the plan (K samples)."""

    t_s: np.ndarray
    s_m: np.ndarray
    """Arc length of the nearest path point (< 0 before the path's start)."""
    transverse_error_m: np.ndarray
    """Distance from the path."""
    attitude_error_deg: np.ndarray
    """Angle of the rotation from the nominal attitude at s to the true one."""
    position_m: np.ndarray
    rpy_rad: np.ndarray
    """(K, 3) true roll, pitch, yaw (ZYX); roll and yaw unwrapped along the flight."""
    velocity_body_m_s: np.ndarray
    """(K, 3) true velocity in the body frame (FRD)."""
    wrench_command: np.ndarray
    """(K, 4) commanded thrust (N) and torques (N m), eq 34 of the rotor commands."""
    rotor_command_n: np.ndarray
    rotor_applied_n: np.ndarray

    def decimated(self, step: int) -> "Trace":
        """Every ``step``-th sample, the last one always kept."""
        idx = np.unique(np.r_[np.arange(0, self.t_s.size, step), self.t_s.size - 1]) if self.t_s.size else []
        return Trace(**{f.name: getattr(self, f.name)[idx] for f in fields(self)})


def truth_trace(plan, flight: Flight) -> Trace:
    """Project every true sample of ``flight`` on ``plan`` (see the module docstring)."""
    k = flight.t_s.size
    s, e = Projector(plan.path).series(flight.position_m)
    R = np.asarray(flight.rotation, dtype=float).reshape(k, 3, 3)
    if k:
        att = rotation_angle_deg(plan.nominal_attitudes(s), R)     # clamped to [0, length]
        rpy = matrix_to_rpy(R)                          # (K, 3)
        rpy[:, 0] = np.unwrap(rpy[:, 0])
        rpy[:, 2] = np.unwrap(rpy[:, 2])
        v_body = np.einsum("kji,kj->ki", R, np.asarray(flight.velocity_m_s, dtype=float))
    else:
        att = np.zeros(0)
        rpy = np.zeros((0, 3))
        v_body = np.zeros((0, 3))
    M = mixer_matrix(plan.vehicle.arm_length_m, plan.vehicle.drag_torque_ratio_m)
    cmd = np.asarray(flight.rotor_command_n, dtype=float).reshape(k, 4)
    return Trace(t_s=np.asarray(flight.t_s, dtype=float), s_m=s, transverse_error_m=e,
                 attitude_error_deg=att, position_m=np.asarray(flight.position_m, dtype=float).reshape(k, 3),
                 rpy_rad=rpy, velocity_body_m_s=v_body, wrench_command=cmd @ M.T, rotor_command_n=cmd,
                 rotor_applied_n=np.asarray(flight.rotor_applied_n, dtype=float).reshape(k, 4))
