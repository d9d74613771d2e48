r"""Tracking metrics against arc length, for ``mavreg simulate`` and ``mavreg fly``.

Given samples ``(s_k, w_k)`` of the longitudinal and transverse coordinates
(docs/conventions.md: ``w[0:2]`` normal/binormal position offset in m, ``w[2:5]`` roll, pitch,
yaw errors in rad):

* transverse error ``e_k = sqrt(w_1^2 + w_2^2)`` (m), the distance to the path point at s;
* attitude error ``a_k = ||wrap(w_3, w_4, w_5)||_2`` (deg), the Euclidean **norm** of the
  three wrapped angle errors (so never smaller than the largest single one). It is not the
  rotation angle between actual and nominal attitude, which needs both rotations; to first
  order that angle is ``||E(phi, theta) dw||`` with ``E`` the Euler-rate matrix
  ``[[1, 0, -s_theta], [0, c_phi, s_phi c_theta], [0, -s_phi, c_phi c_theta]]``, which is
  orthogonal at ``theta = 0`` for any roll: for small nominal pitch (the barrel roll) the
  norm equals the rotation angle to first order; its singular values lie in
  ``[sqrt(1 - |s_theta|), sqrt(1 + |s_theta|)]`` otherwise;

reported as max and RMS over all samples and per named segment. The output is JSON-ready:
plain floats, ints and dicts.
"""
from __future__ import annotations

from typing import Optional, Sequence

import numpy as np

from ..model.rotation import wrap_angle

__all__ = ["tracking_metrics", "error_series", "SATURATION_RTOL", "rotor_jitter_n", "JITTER_CUTOFF_HZ"]

SATURATION_RTOL = 1e-9
"""A rotor counts as saturated when its force is at least ``(1 - 1e-9) * max thrust``."""


def error_series(w) -> tuple[np.ndarray, np.ndarray]:
    """Transverse error (m) and attitude error (deg) of each sample of ``w`` (N, >=5), as
    defined above (what :func:`tracking_metrics` sums up; the figures draw it)."""
    w = np.asarray(w, dtype=float)
    return np.hypot(w[:, 0], w[:, 1]), np.degrees(np.linalg.norm(wrap_angle(w[:, 2:5]), axis=1))


def _stats(values: np.ndarray) -> Optional[dict]:
    if values.size == 0:
        return None
    return {"max": float(values.max()), "rms": float(np.sqrt(np.mean(values ** 2)))}


def _block(mask: np.ndarray, trans: np.ndarray, att: np.ndarray, forces: Optional[np.ndarray],
           saturated: Optional[np.ndarray], dt_s: Optional[float]) -> dict:
    out = {"transverse_error_m": _stats(trans[mask]), "attitude_error_deg": _stats(att[mask])}
    if forces is not None:
        f = forces[mask]
        out["rotor_command_n"] = (None if f.size == 0 else
                                  {"max": float(f.max()), "min": float(f.min())})
    if saturated is not None:
        n_sat = int(np.count_nonzero(saturated[mask]))
        out["saturated_samples"] = n_sat
        out["saturated_s"] = float(n_sat * dt_s)
    return out


def _segment_masks(s: np.ndarray, segments) -> tuple[dict, dict]:
    """Per segment name, which samples lie in it and its ``[s_start, s_end]`` (laps merged;
    see :func:`tracking_metrics`)."""
    segs = [(str(name), float(a), float(b)) for name, a, b in segments]
    for name, a, b in segs:
        if not b > a:
            raise ValueError(f"segment {name!r}: s_end {b} must exceed s_start {a}")
    s_last = max((b for _, _, b in segs), default=np.inf)
    masks: dict[str, np.ndarray] = {}
    bounds: dict[str, list[float]] = {}
    for name, a, b in segs:
        inside = (s >= a) & ((s < b) | ((b == s_last) & (s == b)))
        if name in masks:
            masks[name] |= inside
            bounds[name] = [min(bounds[name][0], a), max(bounds[name][1], b)]
        else:
            masks[name] = inside
            bounds[name] = [a, b]
    return masks, bounds


def tracking_metrics(s, w, segments: Sequence[tuple[str, float, float]],
                     rotor_forces_n=None, max_rotor_thrust_n: Optional[float] = None,
                     dt_s: Optional[float] = None) -> dict:
    """Transverse, attitude and rotor metrics, overall and per segment.

    Parameters
    ----------
    s : (N,) array_like
        Arc length (m) of each sample (it may exceed the path length on later laps; pass
        the segments of every lap).
    w : (N, 11) array_like
        Transverse coordinates; only ``w[:, 0:5]`` are used. Angles are wrapped again to
        (-pi, pi] here, which is harmless if they already are.
    segments : sequence of (name, s_start, s_end)
        A sample belongs to a segment when ``s_start <= s < s_end``; a sample exactly at
        the largest ``s_end`` of all segments belongs to the segments ending there. Segments
        sharing a name (laps) are merged into one entry whose ``s_start_m``/``s_end_m`` are the
        extreme values. Samples outside every segment count only in the totals.
    rotor_forces_n : (N, 4) array_like, optional
        Rotor forces commanded at each sample.
    max_rotor_thrust_n : float, optional
        Per-rotor saturation; with ``rotor_forces_n`` gives ``saturated_s``.
    dt_s : float, optional
        Sample spacing in time; required for ``saturated_s``.

    Returns
    -------
    dict
        ``{"samples", "transverse_error_m": {"max", "rms"}, "attitude_error_deg": {"max",
        "rms"}, ["rotor_command_n": {"max", "min"}], ["saturated_s", "saturated_samples"],
        "segments": {name: {same keys, "s_start_m", "s_end_m", "samples"}}}``. A segment with no
        sample has ``None`` (JSON null) statistics. ``saturated_s`` is the time with any
        rotor at or beyond ``max_rotor_thrust_n``: (number of such samples) * ``dt_s``.

    Raises
    ------
    ValueError
        On empty or mismatched inputs, a segment with ``s_end <= s_start``, or
        ``max_rotor_thrust_n`` without ``rotor_forces_n`` or ``dt_s``.
    """
    s = np.asarray(s, dtype=float)
    w = np.asarray(w, dtype=float)
    if s.ndim != 1 or s.size == 0:
        raise ValueError(f"s must be a non-empty 1-D array, not shape {s.shape}")
    n = s.size
    if w.ndim != 2 or w.shape[0] != n or w.shape[1] < 5:
        raise ValueError(f"w must have shape ({n}, 11), not {w.shape}")
    forces = None
    if rotor_forces_n is not None:
        forces = np.asarray(rotor_forces_n, dtype=float)
        if forces.shape != (n, 4):
            raise ValueError(f"rotor_forces_n must have shape ({n}, 4), not {forces.shape}")
    saturated = None
    if max_rotor_thrust_n is not None:
        if forces is None or dt_s is None:
            raise ValueError("saturated_s needs rotor_forces_n and dt_s with max_rotor_thrust_n")
        if not dt_s > 0.0:
            raise ValueError(f"dt_s must be positive, not {dt_s}")
        limit = float(max_rotor_thrust_n) * (1.0 - SATURATION_RTOL)
        saturated = np.any(forces >= limit, axis=1)

    trans, att = error_series(w)

    out = {"samples": n}
    out.update(_block(np.ones(n, dtype=bool), trans, att, forces, saturated, dt_s))

    masks, bounds = _segment_masks(s, segments)
    out["segments"] = {}
    for name, mask in masks.items():
        block = _block(mask, trans, att, forces, saturated, dt_s)
        block.update({"s_start_m": bounds[name][0], "s_end_m": bounds[name][1],
                      "samples": int(np.count_nonzero(mask))})
        out["segments"][name] = block
    return out


JITTER_CUTOFF_HZ = 20.0
"""Rotor-command jitter is the part above this frequency: a maneuver's own rotor profile
(loops of ~1 s, blends of ~0.4 s) lies well below it; estimator noise fed back lies above."""


def rotor_jitter_n(rotor_forces_n, sample_rate_hz: float, cutoff_hz: float = JITTER_CUTOFF_HZ) -> float:
    """Standard deviation (N) of the high-pass part of rotor commands (N, 4), worst rotor.

    The high pass is a 4th-order Butterworth at ``cutoff_hz``, run forward and backward
    (``scipy.signal.sosfiltfilt``), so a 3 Hz maneuver component leaks by under 1e-3.
    """
    from scipy.signal import butter, sosfiltfilt
    f = np.asarray(rotor_forces_n, dtype=float)
    if f.shape[0] < 64 or cutoff_hz >= sample_rate_hz / 2:
        return 0.0
    sos = butter(4, cutoff_hz, btype="highpass", fs=sample_rate_hz, output="sos")
    return float(np.max(np.std(sosfiltfilt(sos, f, axis=0), axis=0)))
