"""The maneuver file: a path of named segments, a speed profile and a yaw profile along it.

See ``docs/maneuvers.md`` for the format and ``params/maneuvers/barrel_roll.yaml`` for an
example. Angles are degrees in YAML (``*_deg`` keys) and radians inside.

Every number is bounded by what a quadrotor maneuver can mean (docs/maneuvers.md, "Limits"):
positions and lengths by :data:`MAX_EXTENT_M` (the largest geofence the controller file
accepts) and :data:`MIN_LENGTH_M`, speeds by :data:`MIN_SPEED_M_S` and :data:`MAX_SPEED_M_S`, a segment's turn by :data:`MAX_TURN_DEG`, and the
lists by their ``max_items``. What planning would cost is bounded separately, before it
allocates (:mod:`mavreg.maneuver.budget`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from .loader import load_file, load_text
from .ranges import MAX_GEOFENCE_M, MAX_SPEED_M_S

__all__ = ["ManeuverSpec", "SegmentSpec", "load_maneuver", "load_maneuver_text", "maneuver_text_with_laps", "MAX_EXTENT_M",
           "MAX_SPEED_M_S", "MAX_TURN_DEG", "MIN_LENGTH_M", "MIN_SPEED_M_S"]

MAX_EXTENT_M = MAX_GEOFENCE_M
"""1 km: the largest start position, waypoint offset, segment length, radius or pitch. No
part of a maneuver can lie farther from the take-off point than the widest geofence."""
MIN_LENGTH_M = 1e-3
"""1 mm: the shortest segment, radius or speed change (shorter ones ask for unbounded
curvature or acceleration; the path is integrated on 5 mm nodes)."""
MIN_SPEED_M_S = 0.01
"""1 cm/s: slower is hovering, and maneuver regulation needs ds/dt bounded away from 0."""
MAX_TURN_DEG = 3600.0
"""Ten turns in one arc or helix segment; more turns are flown with ``laps``."""

_NAME = {"max_length": 64}
_POS = {"min_exclusive": 0.0, "min": MIN_LENGTH_M, "max": MAX_EXTENT_M}
_OFFSET = {"min": 0.0, "max": MAX_EXTENT_M}
_SPEED = {"min_exclusive": 0.0, "min": MIN_SPEED_M_S, "max": MAX_SPEED_M_S}
_COORD = {"min": -MAX_EXTENT_M, "max": MAX_EXTENT_M}
_TURN = {"deg": True, "min_exclusive": 0.0, "max": MAX_TURN_DEG}


@dataclass(frozen=True)
class StartSpec:
    position_m: tuple[float, ...] = field(metadata={"length": 3, **_COORD})
    """NED position where the path begins (the maneuver's entry point)."""
    heading_rad: float = field(metadata={"deg": True, "min": -360.0, "max": 360.0})
    """Direction of the start tangent, clockwise from north (east = 90 deg)."""
    climb_rad: float = field(default=0.0, metadata={"deg": True, "min": -89.0, "max": 89.0})
    """Start tangent above the horizontal."""


@dataclass(frozen=True)
class LineSpec:
    length_m: float = field(metadata=_POS)


@dataclass(frozen=True)
class ArcSpec:
    radius_m: float = field(metadata=_POS)
    angle_rad: float = field(metadata=_TURN)
    bend_rad: float = field(default=0.0, metadata={"deg": True, "min": -360.0, "max": 360.0})
    """Which way the path turns, about the tangent: 0 up, 90 right, 180 down, -90 left."""


@dataclass(frozen=True)
class HelixSpec:
    radius_m: float = field(metadata=_POS)
    pitch_m: float = field(metadata=_COORD)
    """Rise along the helix axis per full turn (sign gives the handedness)."""
    angle_rad: float = field(metadata=_TURN)
    bend_rad: float = field(default=0.0, metadata={"deg": True, "min": -360.0, "max": 360.0})


@dataclass(frozen=True)
class WaypointsSpec:
    points_m: tuple[tuple[float, ...], ...] = field(
        metadata={"item_length": 3, "min_items": 2, "max_items": 1000, **_COORD})
    """NED offsets from the segment's start point, in order."""


@dataclass(frozen=True)
class SegmentSpec:
    name: str = field(metadata=_NAME)
    line: LineSpec | None = None
    arc: ArcSpec | None = None
    helix: HelixSpec | None = None
    waypoints: WaypointsSpec | None = None
    blend_m: float = field(default=0.0, metadata=_OFFSET)
    """Length of the curvature blend centred on the junction with the previous segment."""

    def __post_init__(self):
        given = [k for k in ("line", "arc", "helix", "waypoints") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"segment {self.name!r} needs exactly one of line, arc, helix, "
                             f"waypoints (got {', '.join(given) or 'none'})")

    @property
    def shape(self):
        return self.line or self.arc or self.helix or self.waypoints


@dataclass(frozen=True)
class SpeedChange:
    segment: str = field(metadata=_NAME)
    length_m: float = field(metadata=_POS)
    to_m_s: float = field(metadata=_SPEED)
    offset_m: float = field(default=0.0, metadata=_OFFSET)
    """Where the change begins: this far after the start of ``segment``, or with
    ``anchor: end`` this far before its end (within the segment: planning refuses an offset
    beyond the segment's length)."""
    anchor: str = field(default="start", metadata={"choices": ("start", "end")})


@dataclass(frozen=True)
class YawChange:
    segment: str = field(metadata=_NAME)
    length_m: float = field(metadata=_POS)
    to_rad: float = field(metadata={"deg": True, "min": -720.0, "max": 720.0})
    offset_m: float = field(default=0.0, metadata=_OFFSET)
    anchor: str = field(default="start", metadata={"choices": ("start", "end")})


@dataclass(frozen=True)
class SpeedSpec:
    initial_m_s: float = field(metadata=_SPEED)
    changes: tuple[SpeedChange, ...] = field(default=(), metadata={"max_items": 100})


@dataclass(frozen=True)
class YawSpec:
    """Where the nose points (docs/maneuvers.md, "Yaw").

    ``mode``: ``fixed`` -- the profile is the yaw itself; ``tangent`` -- the nose follows the
    path's horizontal heading and the profile is an offset from it; ``velocity`` -- the nose
    follows the velocity (the path's tangent, also when it climbs or dives) and the profile
    turns it about the thrust axis.
    """

    initial_rad: float = field(default=0.0, metadata={"deg": True, "min": -360.0, "max": 360.0})
    changes: tuple[YawChange, ...] = field(default=(), metadata={"max_items": 100})
    mode: str = field(default="fixed", metadata={"choices": ("fixed", "tangent", "velocity")})


@dataclass(frozen=True)
class LapsSpec:
    segment: str = field(metadata=_NAME)
    """The arc or helix that is flown ``count`` times: each lap adds a full 360 deg turn."""
    count: int = field(default=1, metadata={"min": 1, "max": 100})


@dataclass(frozen=True)
class LimitsSpec:
    min_speed_m_s: float = field(default=0.2, metadata=_SPEED)
    """Maneuver regulation needs ds/dt bounded away from zero (paper Section 2)."""
    max_tilt_rad: float = field(default=math.pi, metadata={"deg": True, "min_exclusive": 0.0,
                                                           "max": 180.0})
    """Largest nominal tilt (angle of the thrust axis from the vertical; 180 deg: any). A
    plan whose nominal tilts further is infeasible, with where and by how much."""


@dataclass(frozen=True)
class ManeuverSpec:
    name: str = field(metadata=_NAME)
    start: StartSpec
    segments: tuple[SegmentSpec, ...] = field(metadata={"min_items": 1, "max_items": 100})
    speed: SpeedSpec
    yaw: YawSpec = field(default_factory=YawSpec)
    laps: LapsSpec | None = None
    limits: LimitsSpec = field(default_factory=LimitsSpec)
    description: str = ""

    def __post_init__(self):
        names = [s.name for s in self.segments]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            raise ValueError(f"segment names must be unique: {', '.join(sorted(dup))}")
        refs = [c.segment for c in self.speed.changes] + [c.segment for c in self.yaw.changes]
        if self.laps is not None:
            refs.append(self.laps.segment)
        for r in refs:
            if r not in names:
                raise ValueError(f"no segment named {r!r} (segments: {', '.join(names)})")
        if self.segments[0].blend_m > 0:
            raise ValueError(f"the first segment {names[0]!r} has nothing to blend from")

    def with_laps(self, count: int) -> "ManeuverSpec":
        """The same maneuver with its repeated segment flown ``count`` times."""
        from dataclasses import fields, replace
        if self.laps is None:
            raise ValueError(f"maneuver {self.name!r} has no 'laps' segment to repeat")
        bound = next(f.metadata for f in fields(LapsSpec) if f.name == "count")
        if not bound["min"] <= count <= bound["max"]:
            raise ValueError(f"a laps count is {bound['min']} to {bound['max']}, got {count}")
        return replace(self, laps=replace(self.laps, count=count))


def load_maneuver(path: str | Path) -> ManeuverSpec:
    return load_file(path, ManeuverSpec, kind="maneuver")


def load_maneuver_text(text: str, source: str = "<upload>") -> ManeuverSpec:
    return load_text(text, ManeuverSpec, source, kind="maneuver")


def maneuver_text_with_laps(text: str, count: int, source: str = "<upload>") -> str:
    """The maneuver YAML ``text`` with its laps segment flown ``count`` times (``--laps`` of
    ``fly`` and ``upload``: the daemon plans text), validated.

    Raises
    ------
    ConfigError
        ``text`` is not a valid maneuver.
    ValueError
        The maneuver has no laps segment, or ``count`` is out of range
        (:meth:`ManeuverSpec.with_laps`).
    """
    load_maneuver_text(text, source).with_laps(count)
    out = replace_value(text, ("laps", "count"), int(count))
    load_maneuver_text(out, source)
    return out


def replace_value(text: str, keys: tuple[str, ...], value: object) -> str:
    """``text``, YAML that :func:`~mavreg.config.loader.load_text` accepted, with the value at the key path ``keys``
    replaced, as YAML text (its comments are not kept).

    For an override of one value of a file that travels as text (``--laps`` on a maneuver
    the daemon's planner reads); load the result again to validate it.
    """
    doc = yaml.safe_load(text)
    node = doc
    for key in keys[:-1]:
        node = node[key]
    node[keys[-1]] = value
    return yaml.safe_dump(doc, sort_keys=False, allow_unicode=True)
