"""Turn a maneuver's segment list into a :class:`~mavreg.geometry.path.Path`.

Segments are chained: each starts where the previous ends, along its tangent. A turn's
``bend_deg`` is measured about the tangent at the segment's start (at its blend's start if
it has one) from "up" (-z of NED, projected normal to the tangent) towards the right.
A junction where curvature or its slope would jump is rejected unless the later segment
asks for a blend; ``blend_m`` then replaces the last half of the one and the first half of
the other by a C2 curvature blend (see :mod:`mavreg.geometry.segments`).
"""
from __future__ import annotations

import numpy as np

from ..config.maneuver import ManeuverSpec, SegmentSpec
from ..errors import ManeuverError
from .path import Path
from .segments import (CurvaturePiece, arc_piece, blend_piece, helix_piece, line_piece,
                       waypoint_piece)

__all__ = ["build_path", "start_frame", "JUMP_TOL", "SPACING_M"]

SPACING_M = 0.005
"""Arc length between the path's integration nodes (the default of :func:`build_path`)."""

JUMP_TOL = 1e-6
"""Largest curvature (1/m) or curvature-slope (1/m^2) step accepted at a junction."""

_UP = np.array([0.0, 0.0, -1.0])


def start_frame(heading_rad: float, climb_rad: float) -> np.ndarray:
    """Columns (t, m1, m2): t along heading/climb, m1 "up" normal to t, m2 = t x m1."""
    t = np.array([np.cos(climb_rad) * np.cos(heading_rad),
                  np.cos(climb_rad) * np.sin(heading_rad),
                  -np.sin(climb_rad)])
    m1 = _UP - (_UP @ t) * t
    m1 /= np.linalg.norm(m1)
    return np.column_stack([t, m1, np.cross(t, m1)])


def _bend_components(frame: np.ndarray, bend_rad: float) -> np.ndarray:
    """RMF components of the unit bend direction at a frame: 0 = up, pi/2 = right."""
    t, m1, m2 = frame[:, 0], frame[:, 1], frame[:, 2]
    up = _UP - (_UP @ t) * t
    if np.linalg.norm(up) < 1e-9:  # vertical tangent: "up" is taken along m1
        up = m1
    up /= np.linalg.norm(up)
    right = np.cross(t, up)
    d = np.cos(bend_rad) * up + np.sin(bend_rad) * right
    return np.array([d @ m1, d @ m2])


def _piece(seg: SegmentSpec, frame: np.ndarray, laps: int) -> CurvaturePiece:
    """The segment's curvature piece; ``laps - 1`` extra full turns for the laps segment."""
    shp = seg.shape
    extra = 2 * np.pi * (laps - 1)
    if seg.line is not None:
        return line_piece(seg.name, shp.length_m)
    if seg.arc is not None:
        return arc_piece(seg.name, shp.radius_m, shp.angle_rad + extra,
                         _bend_components(frame, shp.bend_rad))
    if seg.helix is not None:
        return helix_piece(seg.name, shp.radius_m, shp.pitch_m, shp.angle_rad + extra,
                           _bend_components(frame, shp.bend_rad))
    try:
        piece, _ = waypoint_piece(seg.name, np.array(shp.points_m), frame[:, 0], frame[:, 1])
    except ValueError as exc:
        raise ManeuverError(f"segment {seg.name!r}: {exc}") from None
    return piece


def _end_state(piece: CurvaturePiece, position: np.ndarray, frame: np.ndarray):
    p = Path([piece], position, frame, spacing_m=min(0.01, piece.length_m / 4))
    return p.c_nodes[-1], p.frame_nodes[-1]


def build_path(spec: ManeuverSpec, spacing_m: float = SPACING_M) -> Path:
    """The path of ``spec``, with its laps segment flown ``spec.laps.count`` times.

    Raises
    ------
    ManeuverError
        A curvature jump without a blend, a blend longer than its segments, or a lap
        count on a segment that cannot repeat.
    """
    laps_seg = spec.laps.segment if spec.laps is not None else None
    segs = spec.segments
    for seg in segs:
        if seg.name == laps_seg and seg.arc is None and seg.helix is None:
            raise ManeuverError(f"laps: segment {seg.name!r} is a "
                                f"{'line' if seg.line else 'waypoint curve'}; only an arc or "
                                "a helix can be flown repeatedly")
    position = np.asarray(spec.start.position_m, dtype=float)
    frame = start_frame(spec.start.heading_rad, spec.start.climb_rad)
    pieces: list[CurvaturePiece] = []
    prev: CurvaturePiece | None = None
    s_junction = 0.0
    for i, seg in enumerate(segs):
        count = spec.laps.count if seg.name == laps_seg else 1
        raw = _piece(seg, frame, count)  # frame: where this segment (or its blend) begins
        end_trim = segs[i + 1].blend_m / 2 if i + 1 < len(segs) else 0.0
        try:
            body = raw.trimmed(seg.blend_m / 2, end_trim)
        except ValueError as exc:
            raise ManeuverError(str(exc)) from None
        if prev is not None:
            if seg.blend_m > 0:
                blend = blend_piece(f"{prev.name}>{seg.name}", seg.blend_m, prev.end(), body.start())
                position, frame = _end_state(blend, position, frame)
                pieces.append(blend)
            else:
                _check_junction(prev.name, seg.name, s_junction, prev.end(), body.start())
        position, frame = _end_state(body, position, frame)
        pieces.append(body)
        s_junction += raw.length_m
        prev = body
    return Path(pieces, spec.start.position_m,
                start_frame(spec.start.heading_rad, spec.start.climb_rad), spacing_m)


def _check_junction(a: str, b: str, s: float, end, start) -> None:
    k0, dk0, _ = end
    k1, dk1, _ = start
    jump = float(np.linalg.norm(k1 - k0))
    if jump > JUMP_TOL:
        raise ManeuverError(
            f"junction {a!r} -> {b!r} at s = {s:.3f} m: curvature jumps by {jump:.4g} 1/m "
            f"(from {np.linalg.norm(k0):.4g} to {np.linalg.norm(k1):.4g}), which needs infinite "
            f"torque; add 'blend_m' (e.g. 2.0) to segment {b!r}")
    slope = float(np.linalg.norm(dk1 - dk0))
    if slope > JUMP_TOL:
        raise ManeuverError(
            f"junction {a!r} -> {b!r} at s = {s:.3f} m: curvature slope jumps by {slope:.4g} "
            f"1/m^2, which needs an infinite torque rate; add 'blend_m' to segment {b!r}")
