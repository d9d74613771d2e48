"""The numbers of the gust and lag tables, from a run's record (pure numpy).

Definitions (every quantity is the truth's, :mod:`.record`):

- **max distance from the path**: the largest transverse error, the distance from the true
  position to its nearest path point (the path's straight extensions included), over the run.
- **time outside the tube**: the time the distance is above :data:`TUBE_M` (0.5 m), each
  sample standing for the interval to the next one.
- **peak acceleration**: the largest magnitude of the true acceleration, the time derivative
  of the true velocity (central differences on the 1 ms record; the gust's own push included).
- **minimum distance to the loop's centre**: the closest the true position comes to the
  centre of the laps segment's circle (1.5 m on the nominal; a vehicle that cuts the loop
  comes closer); none for a run that never reached the loop.
- **overspeed**: the largest ``v_t - v(s)``, the true velocity's component along the path's
  tangent at the vehicle's own arc length s (clamped to the path) above the speed profile
  there: a vehicle racing to catch up with a reference ahead of it flies faster along the
  path than the maneuver prescribes where it is. (Along the tangent, not the speed: a vehicle
  a gust pushes backwards is not too fast, and a sideways excursion is the distance's.)
- **diverged**: the simulation or the flight stopped on a divergence (speed, rate, a
  non-finite state); **completed**: the vehicle's projection reached the path's end in time.
- **late**: the time taken from the start to the path's end minus the nominal's.

``ok`` for these experiments: completed and not diverged.
"""
from __future__ import annotations

import numpy as np

from ..geometry.path import Path
from .metrics import saturated_share

__all__ = ["TUBE_M", "time_above", "peak_acceleration", "overspeed", "along_track_speed", "loop_centre",
           "disturbance_metrics"]

TUBE_M = 0.5
"""The tube around the path whose leaving is counted (m)."""


def time_above(t_s, values, threshold: float) -> float:
    """Time during which ``values`` exceed ``threshold``: sample k counts for [t_k, t_k+1)."""
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(values, dtype=float)
    if t.shape != v.shape or t.ndim != 1:
        raise ValueError(f"t and values must be 1-D arrays of one length, got {t.shape} and {v.shape}")
    if t.size < 2:
        return 0.0
    return float(np.sum(np.diff(t)[v[:-1] > threshold]))


def peak_acceleration(t_s, velocity_m_s) -> float | None:
    """Largest |dv/dt| of a velocity record (K, 3), by central differences (one-sided at the ends)."""
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(velocity_m_s, dtype=float)
    if t.size < 3:
        return None
    a = np.gradient(v, t, axis=0)
    return float(np.max(np.linalg.norm(a, axis=1)))


def overspeed(speed_m_s, s_m, profile_s_m, profile_v_m_s) -> float | None:
    """Largest (along-track) speed above the profile at the same arc length (s clamped to the
    profile's ends)."""
    speed = np.asarray(speed_m_s, dtype=float)
    if speed.size == 0:
        return None
    v = np.interp(np.asarray(s_m, dtype=float), profile_s_m, profile_v_m_s)
    return float(np.max(speed - v))


def along_track_speed(path: Path, s_m, velocity_m_s) -> np.ndarray:
    """Each velocity (K, 3) along the path's unit tangent at its arc length (clamped to the path)."""
    s = np.clip(np.asarray(s_m, dtype=float), 0.0, path.length_m)
    v = np.asarray(velocity_m_s, dtype=float).reshape(-1, 3)
    if s.size == 0:
        return np.zeros(0)
    tangent = path.evaluate(s)[1][:, :, 0]
    return np.einsum("ki,ki->k", tangent, v)


def loop_centre(path: Path, segment: str) -> np.ndarray:
    """Centre of the circle of ``segment`` (an arc): ``c + K / |K|^2`` at its middle, with K
    the curvature vector."""
    spans = [sp for sp in path.spans if sp.name == segment]
    if not spans:
        raise ValueError(f"the path has no segment {segment!r}")
    mid = 0.5 * (spans[0].s_start_m + spans[-1].s_end_m)
    c, F, k, _, _ = path.evaluate(np.array([mid]))
    K = F[0][:, 1:] @ k[0]
    return c[0] + K / float(K @ K)


def disturbance_metrics(plan, trace, flight, spec) -> dict:
    """Every number of one gust or lag run (JSON-ready); see the module docstring."""
    t, e, s = trace.t_s, trace.transverse_error_m, trace.s_m
    n = t.size
    v_t = along_track_speed(plan.path, s, flight.velocity_m_s)
    loop = plan.laps_segment or "loop"
    centre = loop_centre(plan.path, loop)
    dc = np.linalg.norm(trace.position_m - centre, axis=1)
    reached_loop = n > 0 and float(np.max(s)) >= min(a for name, a, _ in plan.segments if name == loop)
    nominal_left = _nominal_time(plan, plan.length_m) - _nominal_time(plan, spec.start_s_m)
    duration = float(t[-1] - t[0]) if n else 0.0
    diverged = flight.status == "diverged"
    completed = bool(flight.completed and flight.status == "completed")
    dt = float(np.median(np.diff(t))) if n > 1 else 0.0
    share = saturated_share(trace.rotor_applied_n, flight.saturation_n)
    m = {
        "index": spec.index, "label": spec.label, "seed": spec.seed, "controller": spec.controller,
        "group": spec.group, "case": spec.case, "saturation_n": spec.saturation_n,
        "gust_force_n": None if spec.gust_force_n is None else list(spec.gust_force_n),
        "gust_window_s": None if spec.gust_window_s is None else list(spec.gust_window_s),
        "start_s_m": spec.start_s_m, "reference_lead_m": spec.reference_lead_m,
        "status": flight.status, "reason": flight.reason, "completed": completed, "diverged": diverged,
        "samples": int(n), "duration_s": duration,
        "late_s": duration - nominal_left if completed else None,
        "max_distance_m": float(np.max(e)) if n else None,
        "outside_tube_s": time_above(t, e, TUBE_M),
        "tube_m": TUBE_M,
        "peak_acceleration_m_s2": peak_acceleration(flight.t_s, flight.velocity_m_s),
        "min_centre_distance_m": float(np.min(dc)) if reached_loop else None,
        "overspeed_m_s": overspeed(v_t, s, plan.s, plan.speed_m_s),
        "max_attitude_error_deg": float(np.max(trace.attitude_error_deg)) if n else None,
        "final_distance_m": float(e[-1]) if n else None,
        "peak_thrust_n": float(trace.wrench_command[:, 0].max()) if n else None,
        "saturated_share": share, "saturated_s": share * n * dt,
        "extra": flight.extra,
    }
    m["ok"] = bool(completed and not diverged)
    return m


def _nominal_time(plan, s_m: float) -> float:
    """Nominal time from the path's start to arc length ``s_m`` (trapezoid on the plan's grid)."""
    s = np.clip(plan.s, None, s_m)
    v = plan.speed_m_s
    return float(np.sum(np.diff(s) * 2 / (v[1:] + v[:-1])))
