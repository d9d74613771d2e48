"""The numbers of an experiment's tables, from a run's :class:`~.record.Trace` (pure numpy).

Definitions (every error is the truth's, :mod:`.record`):

- **converged, arc length at convergence**: the run converged when its transverse error
  falls below :data:`CONVERGED_M` (1 cm) and stays below it until the vehicle reaches
  ``before_s`` (the end of the first segment: for the barrel roll the run-up's end,
  s = 16.5 m, where the path starts to bend into the loop). The arc length at convergence
  is the vehicle's s at the first sample of that final stretch below 1 cm (a run that
  starts within 1 cm converged at its first sample). Samples are taken in time order up to
  the first one at or past ``before_s``; a run that never gets there did not converge.
- **loop**: the samples whose s lies in the laps segment ``[start, end)`` (every lap); max
  and RMS transverse error, max attitude error there.
- **peaks**: of the commanded thrust and of each torque's magnitude (eq 34 of the rotor
  commands), over the whole maneuver (in group 1: the start's transient), from convergence
  to the end (the maneuver's own) and in the loop.
- **saturated**: a sample with any rotor's applied force at the plant's limit
  (``>= (1 - 1e-9) limit``); the share is over the samples of the maneuver. Also the time
  during which all four rotors are asked for at least the limit: they all give the limit (up
  to the noise), so no differential thrust, hence no torque, is left whatever is asked.
- **torque shortfall**: in the loop, the largest difference between each torque the rotor
  commands ask for and the one the applied rotor forces give (saturation, and the noise:
  0.1 N per rotor is about 0.04 N m of SD on the roll and pitch torques).
- **laps flown**: ``laps * clip((max s - loop start) / (loop end - loop start), 0, 1)``.
- **stable**: the maneuver was flown to the end of its path (every lap, no divergence, not
  stopped by the daemon's envelope) and the vehicle is back within :data:`BACK_ON_PATH_M`
  of the path at the end.
"""
from __future__ import annotations

import numpy as np

from ..model.mixer import mixer_matrix
from ..sim.metrics import SATURATION_RTOL
from .definitions import CONVERGENCE

__all__ = ["CONVERGED_M", "BACK_ON_PATH_M", "convergence_arc_length", "saturated_share",
           "laps_flown", "stats", "run_metrics", "run_ok"]

CONVERGED_M = 0.01
"""Converged: transverse error below 1 cm (the unperturbed loop flies within 1.2 mm)."""
BACK_ON_PATH_M = 0.10
"""Stable: back within 10 cm of the path at the end of the maneuver."""


def convergence_arc_length(s_m, error_m, threshold_m: float, before_s_m: float) -> float | None:
    """Arc length from which ``error_m`` stays below ``threshold_m`` until ``before_s_m``.

    Parameters
    ----------
    s_m, error_m : (K,) array_like
        Arc length and error of each sample, in time order.
    threshold_m : float
    before_s_m : float
        The error must have converged by the time s first reaches this.

    Returns
    -------
    float or None
        The s of the first sample of the final stretch below the threshold before
        ``before_s_m``; None when there is no such stretch (the error is at or above the
        threshold at the last sample before it, s never reaches it, or no sample precedes it).
    """
    s = np.asarray(s_m, dtype=float)
    e = np.asarray(error_m, dtype=float)
    if s.shape != e.shape or s.ndim != 1:
        raise ValueError(f"s and error must be 1-D arrays of one length, got {s.shape} and {e.shape}")
    reached = np.flatnonzero(s >= before_s_m)
    if reached.size == 0 or reached[0] == 0:
        return None
    before = e[:reached[0]]
    above = np.flatnonzero(~(before < threshold_m))        # NaN counts as not converged
    if above.size == 0:
        return float(s[0])
    last = above[-1]
    if last == before.size - 1:
        return None
    return float(s[last + 1])


def saturated_share(forces_n, limit_n: float | None, every_rotor: bool = False) -> float:
    """Share of samples (rows of ``forces_n``, (K, 4)) with any rotor at or beyond ``limit_n``
    (with ``every_rotor``: all four at once)."""
    f = np.asarray(forces_n, dtype=float)
    if limit_n is None or f.size == 0:
        return 0.0
    at = f >= float(limit_n) * (1.0 - SATURATION_RTOL)
    sat = np.all(at, axis=1) if every_rotor else np.any(at, axis=1)
    return float(np.count_nonzero(sat) / sat.size)


def laps_flown(s_m, loop_start_m: float, loop_end_m: float, laps: int) -> float:
    """Laps of the laps segment flown, from the largest arc length reached."""
    s = np.asarray(s_m, dtype=float)
    if s.size == 0:
        return 0.0
    frac = (float(np.max(s)) - loop_start_m) / (loop_end_m - loop_start_m)
    return float(laps * min(max(frac, 0.0), 1.0))


def stats(values) -> dict | None:
    """``{"max", "rms"}`` of the values, None when there are none."""
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return None
    return {"max": float(np.max(v)), "rms": float(np.sqrt(np.mean(v * v)))}


def _loop_span(plan) -> tuple[float, float]:
    name = plan.laps_segment or "loop"
    spans = [(a, b) for n, a, b in plan.segments if n == name]
    if not spans:
        raise ValueError(f"plan {plan.name!r} has no segment {name!r} to judge the loop on")
    return min(a for a, _ in spans), max(b for _, b in spans)


def run_metrics(plan, trace, flight, spec, kind: str) -> dict:
    """Every number of one run (JSON-ready); see the module docstring for the definitions.

    Parameters
    ----------
    plan : Plan
        What the run flew (its laps included).
    trace : Trace
    flight : Flight
    spec : RunSpec
    kind : str
        The experiment's kind; decides ``ok`` (:func:`run_ok`).
    """
    loop_a, loop_b = _loop_span(plan)
    s, e, att = trace.s_m, trace.transverse_error_m, trace.attitude_error_deg
    in_loop = (s >= loop_a) & (s < loop_b)
    first_end = plan.segments[0][2]
    s_conv = convergence_arc_length(s, e, CONVERGED_M, first_end)
    t_conv = None
    wrench = np.abs(trace.wrench_command)
    after = np.zeros(s.size, dtype=bool)
    if s_conv is not None:
        k_conv = int(np.flatnonzero(s == s_conv)[0])
        t_conv = float(trace.t_s[k_conv])
        after[k_conv:] = True
    M = mixer_matrix(plan.vehicle.arm_length_m, plan.vehicle.drag_torque_ratio_m)
    shortfall = np.abs(trace.wrench_command - trace.rotor_applied_n @ M.T)[in_loop, 1:]
    n = s.size
    tail = s >= plan.length_m - 1.0
    final_e = float(np.max(e[tail])) if np.any(tail) else None
    dt = float(np.median(np.diff(trace.t_s))) if n > 1 else 0.0
    share = saturated_share(trace.rotor_applied_n, flight.saturation_n)
    m = {
        "index": spec.index, "label": spec.label, "seed": spec.seed,
        "offset_m": list(spec.offset_m),
        "inertia_kg_m2": None if spec.inertia_kg_m2 is None else list(spec.inertia_kg_m2),
        "rotor_noise_sd_n": spec.rotor_noise_sd_n, "saturation_n": spec.saturation_n, "laps": spec.laps,
        "status": flight.status, "reason": flight.reason, "completed": bool(flight.completed),
        "samples": int(n),
        "duration_s": float(trace.t_s[-1] - trace.t_s[0]) if n else 0.0,
        "start_distance_m": float(e[0]) if n else None,
        "converged": s_conv is not None, "converged_at_s_m": s_conv, "converged_at_t_s": t_conv,
        "converge_before_s_m": first_end,
        "loop": {"s_start_m": loop_a, "s_end_m": loop_b, "transverse_error_m": stats(e[in_loop]),
                 "attitude_error_deg": stats(att[in_loop])},
        "overall": {"transverse_error_m": stats(e), "attitude_error_deg": stats(att)},
        "final_transverse_error_m": final_e,
        "peak_thrust_n": float(trace.wrench_command[:, 0].max()) if n else None,
        "peak_torque_n_m": [float(x) for x in wrench[:, 1:].max(axis=0)] if n else None,
        "converged_peak_thrust_n": float(trace.wrench_command[after, 0].max()) if np.any(after) else None,
        "converged_peak_torque_n_m": ([float(x) for x in wrench[after, 1:].max(axis=0)]
                                      if np.any(after) else None),
        "loop_peak_thrust_n": float(trace.wrench_command[in_loop, 0].max()) if np.any(in_loop) else None,
        "loop_peak_torque_n_m": ([float(x) for x in wrench[in_loop, 1:].max(axis=0)]
                                 if np.any(in_loop) else None),
        "peak_rotor_command_n": float(trace.rotor_command_n.max()) if n else None,
        "saturated_share": share, "saturated_s": share * n * dt,
        "all_rotors_asked_beyond_limit_s": saturated_share(trace.rotor_command_n, flight.saturation_n,
                                                           every_rotor=True) * n * dt,
        "loop_torque_shortfall_n_m": [float(x) for x in shortfall.max(axis=0)] if shortfall.size else None,
        "laps_flown": laps_flown(s, loop_a, loop_b, plan.laps),
        "extra": flight.extra,
    }
    m["stable"] = bool(flight.completed and flight.status == "completed" and final_e is not None
                       and final_e < BACK_ON_PATH_M)
    m["ok"] = run_ok(m, kind)
    return m


def run_ok(m: dict, kind: str) -> bool:
    """The experiment's criterion for one run: converged before the loop and completed
    (convergence), or stable (saturation)."""
    if kind == CONVERGENCE:
        return bool(m["converged"] and m["completed"])
    return bool(m["stable"])
