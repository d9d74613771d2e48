"""Where each named segment lies along the path, and the speed and yaw profiles placed on it.

A segment begins at the middle of its blend (where the previous segment would have ended
without one) and ends where the next begins, so the places are the running sum of the
segments' own lengths: :func:`raw_segment_bounds` knows them from the maneuver file alone,
before any path is built (the planning budget needs them), and :func:`segment_starts` and
:func:`segment_ends` read them off a built path.
"""
from __future__ import annotations

import math

from ..config.maneuver import ManeuverSpec, SegmentSpec
from ..errors import UsageError
from ..geometry.path import Path
from .profiles import Profile

__all__ = ["segment_starts", "segment_ends", "build_profiles", "profiles_at", "raw_segment_length",
           "raw_segment_bounds"]


def segment_starts(path: Path) -> dict[str, float]:
    """Arc length where each named segment begins (the middle of its blend, if any)."""
    starts = {}
    for i, sp in enumerate(path.spans):
        if sp.kind == "blend":
            continue
        prev = path.spans[i - 1] if i > 0 else None
        starts[sp.name] = ((prev.s_start_m + prev.s_end_m) / 2
                           if prev is not None and prev.kind == "blend" else sp.s_start_m)
    return starts


def segment_ends(path: Path) -> dict[str, float]:
    """Arc length where each named segment ends (the start of the next, or the path's end)."""
    starts = segment_starts(path)
    names = list(starts)
    return {n: (starts[names[i + 1]] if i + 1 < len(names) else path.length_m)
            for i, n in enumerate(names)}


def raw_segment_length(seg: SegmentSpec, laps: int = 1) -> float:
    """A segment's length from its parameters, with ``laps - 1`` extra full turns for an arc
    or a helix; a waypoint curve's is the length of its polygon (the curve is a little
    longer)."""
    if seg.line is not None:
        return seg.line.length_m
    turns = 2 * math.pi * (laps - 1)
    if seg.arc is not None:
        return seg.arc.radius_m * (seg.arc.angle_rad + turns)
    if seg.helix is not None:
        h = seg.helix
        return math.hypot(h.radius_m, h.pitch_m / (2 * math.pi)) * (h.angle_rad + turns)
    pts = [(0.0, 0.0, 0.0)] + list(seg.waypoints.points_m)
    return sum(math.dist(a, b) for a, b in zip(pts[:-1], pts[1:]))


def raw_segment_bounds(spec: ManeuverSpec) -> tuple[dict[str, float], dict[str, float]]:
    """Start and end arc length of each segment, from the file alone (laps included)."""
    laps_seg = spec.laps.segment if spec.laps is not None else None
    starts, ends, s = {}, {}, 0.0
    for seg in spec.segments:
        starts[seg.name] = s
        s += raw_segment_length(seg, spec.laps.count if seg.name == laps_seg else 1)
        ends[seg.name] = s
    return starts, ends


def _profile(initial, changes, starts, ends, what) -> Profile:
    steps = []
    for c in changes:
        seg_m = ends[c.segment] - starts[c.segment]
        if c.offset_m > seg_m + 1e-9:
            raise UsageError(f"{what}: a change on {c.segment!r} at offset_m {c.offset_m:g} lies "
                             f"beyond the segment's {seg_m:.2f} m (anchor {c.anchor})")
        steps.append((starts[c.segment] + c.offset_m if c.anchor == "start"
                      else ends[c.segment] - c.offset_m, c.length_m,
                      c.to_m_s if what == "speed" else c.to_rad))
    try:
        return Profile(initial, tuple(sorted(steps)))
    except ValueError as exc:
        raise UsageError(f"{what}: {exc}") from None


def profiles_at(spec: ManeuverSpec, starts: dict[str, float],
                ends: dict[str, float]) -> tuple[Profile, Profile]:
    """The speed (m/s) and yaw (rad) profiles of ``spec`` with its segments at ``starts`` and
    ``ends`` (arc lengths).

    Raises
    ------
    UsageError
        A change whose offset lies beyond its segment, or changes that overlap.
    """
    return (_profile(spec.speed.initial_m_s, spec.speed.changes, starts, ends, "speed"),
            _profile(spec.yaw.initial_rad, spec.yaw.changes, starts, ends, "yaw"))


def build_profiles(spec: ManeuverSpec, path: Path) -> tuple[Profile, Profile]:
    """The speed (m/s) and yaw (rad) profiles of ``spec`` along ``path``."""
    return profiles_at(spec, segment_starts(path), segment_ends(path))
