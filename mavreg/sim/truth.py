"""True errors of a flown maneuver: recorded positions and attitudes against the plan.

The controller's own errors (``w``) are measured on what it saw: an estimate, perhaps a
prediction. A simulator's or emulator's record has the truth. Each true position is
projected on the path (warm-started, as the regulator does), giving the true transverse
error at the true arc length s; the true attitude is compared with the nominal attitude at
that s by the angle of the rotation between them, :math:`\\arccos((\\mathrm{tr}(\\bar R^T R) - 1)/2)`;
the true speed with the profile's speed at that s (its excess over the profile is a
catch-up). Samples whose projection falls outside (0, length) are left out. The
projection is one compiled loop where numba is in use
(:meth:`~mavreg.geometry.projection.Projector.series`); the rest is numpy.
"""
from __future__ import annotations

import numpy as np

from ..geometry.projection import Projector
from ..model.rotation import quats_to_matrices
from ..model.so3 import rotation_angle_deg

__all__ = ["true_errors", "true_error_series", "quats_to_matrices"]


def _stats(e: np.ndarray, key: str) -> dict:
    if e.size == 0:
        return {f"max_{key}": None, f"rms_{key}": None}
    return {f"max_{key}": float(e.max()), f"rms_{key}": float(np.sqrt(np.mean(e * e)))}


def true_error_series(plan, positions_m, rotations=None, velocities_m_s=None) -> dict:
    """The true errors sample by sample (what :func:`true_errors` sums up; the figures draw it).

    Parameters
    ----------
    plan : Plan
    positions_m : (K, 3) true NED positions, in time order.
    rotations : (K, 3, 3) true body-to-NED rotations, optional.
    velocities_m_s : (K, 3) true NED velocities, optional.

    Returns
    -------
    dict
        ``index`` (the samples kept: projection inside (0, length)), ``s_m``,
        ``transverse_m``, and with their inputs ``attitude_deg`` (the rotation angle to the
        nominal at s) and ``speed_excess_m_s`` (``|v| - v(s)``); arrays of the kept samples.
    """
    s_all, e_all = Projector(plan.path).series(np.asarray(positions_m, dtype=float).reshape(-1, 3))
    keep = np.flatnonzero((s_all > 0.0) & (s_all < plan.length_m))
    out = {"index": keep, "s_m": s_all[keep], "transverse_m": e_all[keep]}
    if rotations is not None:
        Rt = np.asarray(rotations, dtype=float).reshape(-1, 3, 3)[keep]
        out["attitude_deg"] = rotation_angle_deg(plan.nominal_attitudes(out["s_m"]), Rt)
    if velocities_m_s is not None:
        speed = np.linalg.norm(np.asarray(velocities_m_s, dtype=float).reshape(-1, 3)[keep], axis=1)
        out["speed_excess_m_s"] = speed - np.interp(out["s_m"], plan.s, plan.speed_m_s)
    return out


def true_errors(plan, positions_m, rotations=None, velocities_m_s=None) -> dict:
    """True transverse (m), attitude (deg) and speed (m/s) errors, overall and per segment.

    Parameters
    ----------
    plan : Plan
    positions_m : (K, 3) true NED positions, in time order.
    rotations : (K, 3, 3) true body-to-NED rotations, optional.
    velocities_m_s : (K, 3) true NED velocities, optional.

    Returns
    -------
    dict
        ``{"samples", "max_m", "rms_m", ["max_deg", "rms_deg"], ["max_speed_error_m_s",
        "rms_speed_error_m_s", "max_overspeed_m_s"], "segments": {name: {...}}}``; the speed
        error is ``| |v| - v(s) |``, the overspeed ``max(|v| - v(s))``.
    """
    series = true_error_series(plan, positions_m, rotations, velocities_m_s)
    s_arr, e_arr = series["s_m"], series["transverse_m"]
    a_arr = series.get("attitude_deg")
    dv_arr = series.get("speed_excess_m_s")

    def stats(mask):
        d = _stats(e_arr[mask], "m")
        if a_arr is not None:
            d.update(_stats(a_arr[mask], "deg"))
        if dv_arr is not None:
            dv = dv_arr[mask]
            d.update(_stats(np.abs(dv), "speed_error_m_s"))
            d["max_overspeed_m_s"] = float(dv.max()) if dv.size else None
        return d

    out = {"samples": int(e_arr.size), **stats(np.ones(e_arr.size, bool)), "segments": {}}
    for name, a, b in plan.segments:
        mask = (s_arr >= a) & (s_arr < b) if s_arr.size else np.zeros(0, bool)
        out["segments"][name] = stats(mask)
    return out
