"""True errors of a flown maneuver: recorded positions and attitudes against the plan.

The controller's own errors (``w``) are measured on what it saw: an estimate, perhaps a
prediction. A simulator's or emulator's record has the truth. Each true position is
projected on the path (warm-started, as the regulator does), giving the true transverse
error at the true arc length s; the true attitude is compared with the nominal attitude at
that s by the angle of the rotation between them, :math:`\\arccos((\\mathrm{tr}(\\bar R^T R) - 1)/2)`;
the true speed with the profile's speed at that s (its excess over the profile is a
catch-up). Samples whose projection falls outside (0, length) are left out. Pure numpy.
"""
from __future__ import annotations

import numpy as np

from ..geometry.projection import Projector
from ..model.rotation import quats_to_matrices

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
    proj = Projector(plan.path)
    pts = np.asarray(positions_m, dtype=float)
    keep, s_all, e_all = [], [], []
    for i, p in enumerate(pts):
        pr = proj.reset(p, 0.0) if i == 0 else proj.update(p)
        if 0.0 < pr.s < plan.length_m:
            keep.append(i)
            s_all.append(pr.s)
            e_all.append(pr.distance_m)
    out = {"index": np.array(keep, dtype=int), "s_m": np.array(s_all), "transverse_m": np.array(e_all)}
    if rotations is not None:
        Rt = np.asarray(rotations, dtype=float)[keep]
        a_arr = np.empty(len(keep))
        for j, (s, R) in enumerate(zip(out["s_m"], Rt)):
            Rn = plan.nominal_attitude(s)
            c = (float(np.sum(Rn * R)) - 1.0) / 2.0
            a_arr[j] = np.degrees(np.arccos(min(max(c, -1.0), 1.0)))
        out["attitude_deg"] = a_arr
    if velocities_m_s is not None:
        speed = np.linalg.norm(np.asarray(velocities_m_s, dtype=float)[keep], axis=1)
        out["speed_excess_m_s"] = (speed - np.interp(out["s_m"], plan.s, plan.speed_m_s) if keep
                                   else np.zeros(0))
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
