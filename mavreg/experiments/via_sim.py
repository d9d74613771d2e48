"""Fly one run on the design model (``--via sim``): the regulator at 1 kHz, RK4 at 1 ms.

The sequential simulator of :mod:`mavreg.sim.maneuver_run` (zero-order hold, the plant's
inertia, rotor noise drawn once per control period from the run's seed, per-rotor
saturation of the plant only). The controller is the plan's nominal design; the run starts
at the nominal entry state plus the run's offset, with the entry's velocity.
"""
from __future__ import annotations

import numpy as np

from ..model.rotation import rpy_to_matrix
from ..sim.maneuver_run import fly_on_design_model
from .record import Flight

__all__ = ["fly_sim"]


def fly_sim(plan, spec) -> Flight:
    """Fly ``spec`` (:class:`~.definitions.RunSpec`) on the design model; the true record."""
    run = fly_on_design_model(plan, offset_m=spec.offset_m, inertia_kg_m2=spec.inertia_kg_m2,
                              rotor_noise_sd_n=spec.rotor_noise_sd_n, saturation_n=spec.saturation_n,
                              seed=spec.seed)
    res = run.result
    x = res.x
    R = rpy_to_matrix(*x[:, 3:6].T).transpose(2, 0, 1)
    v_ned = np.einsum("kij,kj->ki", R, x[:, 6:9])
    status = res.status.value
    return Flight(t_s=res.t, position_m=x[:, :3], rotation=R, velocity_m_s=v_ned,
                  rotor_command_n=res.rotor_command_n, rotor_applied_n=res.rotor_applied_n,
                  status=status, reason=res.reason, completed=status == "completed",
                  saturation_n=spec.saturation_n, extra={})
