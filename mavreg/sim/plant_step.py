"""One physics step of the design model, as :func:`mavreg.sim.closed_loop.simulate` takes it.

:class:`RpyStep` integrates roll-pitch-yaw (the paper's state), :class:`So3Step` the attitude
as a rotation matrix (no singularity at 90 degrees of pitch). Both are classical RK4 with
the input and an external force held over the step; each is a compiled kernel where numba
is in use (:mod:`mavreg.model.quadrotor_kernel`) and numpy otherwise, the reference
(``tests/unit/test_quadrotor_kernel.py`` holds them together).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from ..accel import use_compiled
from ..model.quadrotor import NX, QuadrotorModel
from ..model.quadrotor_kernel import rk4_so3_step, rk4_step
from ..model.rotation import matrix_to_rpy, rpy_to_matrix
from ..model.so3 import hat

__all__ = ["RpyStep", "So3Step", "KernelArgs"]


class So3Step:
    """One RK4 step of the plant with its attitude as a rotation matrix.

    The step integrates y = (p, R, v, w) with p' = R v, R' = R hat(w) and the body dynamics
    of the design model (:meth:`QuadrotorModel.body_derivatives`); R is then brought back to
    SO(3) by one Newton step of the polar decomposition, R (3 I - R^T R) / 2 (the RK4 drift
    is O(dt^5) per step). The state in and out is the usual x, roll-pitch-yaw included; the
    rotation is carried between steps, so roll-pitch-yaw is only ever read out, never
    integrated. Compiled where numba is in use
    (:func:`~mavreg.model.quadrotor_kernel.rk4_so3_step`); this numpy step is the reference.
    """

    def __init__(self, plant: QuadrotorModel, compiled: Optional[bool] = None):
        self.plant = plant
        self.R: Optional[np.ndarray] = None
        self._x_last: Optional[np.ndarray] = None
        self._kernel = KernelArgs(plant, 18) if use_compiled(compiled, "plant step") else None

    def _deriv(self, R, v, w, u, F):
        vdot, wdot = self.plant.body_derivatives(R[2], v, w, u)
        if F is not None:
            vdot = vdot + R.T @ F
        return R @ v, R @ hat(w), vdot, wdot

    def __call__(self, x: np.ndarray, u: np.ndarray, F, dt: float) -> np.ndarray:
        if self.R is None or self._x_last is None or not np.array_equal(x, self._x_last):
            self.R = rpy_to_matrix(x[3], x[4], x[5])
        if self._kernel is not None:
            return self._compiled(x, u, F, dt)
        R, v, w = self.R, x[6:9], x[9:12]
        k1 = self._deriv(R, v, w, u, F)
        k2 = self._deriv(R + 0.5 * dt * k1[1], v + 0.5 * dt * k1[2], w + 0.5 * dt * k1[3], u, F)
        k3 = self._deriv(R + 0.5 * dt * k2[1], v + 0.5 * dt * k2[2], w + 0.5 * dt * k2[3], u, F)
        k4 = self._deriv(R + dt * k3[1], v + dt * k3[2], w + dt * k3[3], u, F)
        d = [(a + 2.0 * (b + c) + e) * (dt / 6.0) for a, b, c, e in zip(k1, k2, k3, k4)]
        R = R + d[1]
        R = R @ (3.0 * np.eye(3) - R.T @ R) / 2.0
        self.R = R
        out = np.concatenate([x[0:3] + d[0], matrix_to_rpy(R), v + d[2], w + d[3]])
        self._x_last = out
        return out

    def _compiled(self, x: np.ndarray, u: np.ndarray, F, dt: float) -> np.ndarray:
        """The step by :func:`~mavreg.model.quadrotor_kernel.rk4_so3_step`."""
        k = self._kernel
        y = np.concatenate([x[0:3], self.R.reshape(9), x[6:12]])
        rk4_so3_step(y, float(u[0]), float(u[1]), float(u[2]), float(u[3]), k.force_of(F), k.plant, *k.J,
                     float(dt), k.work)
        self.R = y[3:12].reshape(3, 3)
        out = np.concatenate([y[0:3], matrix_to_rpy(self.R), y[12:18]])
        self._x_last = out
        return out


class KernelArgs:
    """What a compiled plant step takes besides the state: the plant's numbers, its inertia,
    scratch, and the external acceleration held over the step (``(a_N, a_E, a_D, on)``)."""

    def __init__(self, plant: QuadrotorModel, width: int):
        self.plant = plant.kernel_params
        self.J = tuple(float(j) for j in plant.inertia_kg_m2)
        self.work = tuple(np.empty(width) for _ in range(5))
        self._force = np.zeros(4)

    def force_of(self, F) -> np.ndarray:
        """The kernels' force argument for ``F`` (m/s^2, NED; None: no force)."""
        if F is None:
            self._force[3] = 0.0
        else:
            self._force[:3] = F
            self._force[3] = 1.0
        return self._force


class RpyStep:
    """One classical RK4 step of the design model with roll-pitch-yaw integrated, an external
    force over mass ``F`` (m/s^2, NED) held over the step: the compiled step
    (:func:`~mavreg.model.quadrotor_kernel.rk4_step`) where numba is in use, else this
    numpy one (the reference: ``tests/unit/test_quadrotor_kernel.py``)."""

    def __init__(self, plant: QuadrotorModel, compiled: Optional[bool] = None):
        self.f = plant.f
        self._kernel = KernelArgs(plant, NX) if use_compiled(compiled, "plant step") else None

    def _deriv(self, x: np.ndarray, u: np.ndarray, F: Optional[np.ndarray]) -> np.ndarray:
        dx = self.f(x, u)
        if F is not None:
            dx[6:9] += rpy_to_matrix(x[3], x[4], x[5]).T @ F
        return dx

    def __call__(self, x: np.ndarray, u: np.ndarray, F, dt: float) -> np.ndarray:
        k = self._kernel
        if k is not None:
            out = np.array(x, dtype=float)
            rk4_step(out, float(u[0]), float(u[1]), float(u[2]), float(u[3]), k.force_of(F), k.plant, *k.J,
                     float(dt), k.work)
            return out
        k1 = self._deriv(x, u, F)
        k2 = self._deriv(x + 0.5 * dt * k1, u, F)
        k3 = self._deriv(x + 0.5 * dt * k2, u, F)
        k4 = self._deriv(x + dt * k3, u, F)
        return x + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)
