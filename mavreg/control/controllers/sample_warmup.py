r"""Compile the daemon's per-sample kernels before the loop, not in it.

The forecaster's prediction (:mod:`mavreg.control.estimation.predictor_kernel`), the disturbance
observer's update (:mod:`mavreg.control.estimation.observer_kernel`) and the hover step
(:mod:`mavreg.control.controllers.hover_kernel`) are numba kernels compiled on their first call. On a
machine whose numba cache is cold (a fresh clone, or any kernel file edited since, which
re-stamps every kernel's cache: :mod:`mavreg.accel`) that first call takes seconds, and it
falls in the take-off's first control period: the vehicle sees no command for that long and
its failsafe takes over (a lockstep flight so started left OFFBOARD 0.27 s into its take-off).

:func:`warm_up_sample_kernels` runs throwaway copies of those objects, built as the daemon
builds its own, through a few samples of a hover (the observer on, the estimate fed
forward and not, a gap-filling prediction, a ramp and a hold): numba compiles for the
argument types, not their values, so these calls compile (or load from the on-disk cache)
every specialization the loop will call. The maneuver regulator's kernel is warmed when the
regulator is built (:func:`mavreg.control.controllers.fastpath.warm_up`). No clock is read here: a caller
that wants the warm-up timed times the call.
"""
from __future__ import annotations

import numpy as np

from ...accel import ACCELERATED
from ...config.disturbance import DisturbanceParams
from ...config.vehicle import G, VehicleParams
from ..estimation.forecast import Forecaster
from .hover import HoverController, HoverParams, hold_ramp, plan_ramp

__all__ = ["warm_up_sample_kernels"]

_SAMPLES = 4
_DELAY_S = 0.014


def warm_up_sample_kernels(vehicle: VehicleParams, control_period_s: float, max_horizon_s: float,
                           disturbance: DisturbanceParams | None, hover: HoverParams) -> bool:
    """Run the per-sample kernels once on a hover; True when they ran (and are now compiled),
    False on the pure path (nothing to compile). The caller's own objects are not touched."""
    if not ACCELERATED:
        return False
    fc = Forecaster(vehicle, control_period_s, predict=True, max_horizon_s=max_horizon_s, disturbance=disturbance)
    ctl = HoverController(vehicle, hover)
    hover_n = np.full(4, vehicle.mass_kg * G / 4.0)
    fc.reset(hover_n)
    fc.observing = True
    x = np.zeros(12)
    x[2], x[6] = -1.0, 1.0                       # 1 m up, moving (the observer learns drag)
    ramps = (plan_ramp(x[:3], np.zeros(3), 0.0, x[:3] + np.array([0.0, 0.0, -1.0]), np.zeros(3), 0.0, hover),
             hold_ramp(x[:3], 0.0))
    for k in range(_SAMPLES):
        t = k * control_period_s
        f = fc.update(t, x, np.eye(3), _DELAY_S)
        for ramp in ramps:
            for estimate in (None, fc.disturbance):
                out = ctl.step(f.x, ramp, t, estimate)
        fc.command(t, out.rotor_forces_n)
        fc.ahead(t, x, np.eye(3), control_period_s, _DELAY_S)
    return True
