"""Every number of the vehicle and controller files at its bounds and just past them (issue 32,
item 4): generated from the schemas' field metadata (mavreg.config.ranges), so a field added
without a range fails here.

At each bound the file loads; one step of a float past it (``math.nextafter``; 1 for an
integer) it is refused in one line naming the file, the key, the value and the range. Pure
loading: nothing is planned (tests/unit/test_bounds_planning.py plans a few corners).
"""
from __future__ import annotations

import copy
import dataclasses
import math
import typing
from typing import NamedTuple

import pytest
import yaml

from mavreg.config.controller import ControllerParams, load_controller
from mavreg.config.loader import ConfigError, load_text
from mavreg.config.loader import _unwrap_optional, _yaml_key as _key     # the loader's own rules
from mavreg.config.maneuver import load_maneuver
from mavreg.config.paths import controller_file, maneuver_files, params_dir, vehicle_file
from mavreg.config.vehicle import VehicleParams, load_vehicle

SOURCE = "bounds.yaml"
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)     # libyaml when there is one


class Number(NamedTuple):
    path: tuple[str, ...]       # YAML keys from the top
    length: int | None          # None: a scalar; else a vector of this many
    lo: float
    hi: float
    is_int: bool


def numbers(schema, prefix: tuple[str, ...] = ()) -> list[Number]:
    """Every numeric field of ``schema`` and its nested sections, with its range."""
    out = []
    hints = typing.get_type_hints(schema)
    for f in dataclasses.fields(schema):
        tp, path, meta = _unwrap_optional(hints[f.name])[0], prefix + (_key(f),), f.metadata
        if dataclasses.is_dataclass(tp):
            out += numbers(tp, path)
            continue
        elem = typing.get_args(tp)[0] if typing.get_origin(tp) is tuple else tp
        if elem not in (int, float):
            continue
        assert "min" in meta and "max" in meta, f"{'.'.join(path)} has no two-sided range: {dict(meta)}"
        assert "min_exclusive" not in meta and "max_exclusive" not in meta, path    # a sign is no bound
        out.append(Number(path, meta.get("length") if elem is not tp else None, meta["min"], meta["max"],
                          elem is int))
    return out


def as_document(obj) -> dict:
    """A loaded schema written back as a YAML mapping (every key, degrees where the file has them)."""
    doc = {}
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if value is None:
            continue
        if dataclasses.is_dataclass(value):
            value = as_document(value)
        elif f.metadata.get("deg"):
            value = math.degrees(value)
        elif isinstance(value, tuple):
            value = [as_document(v) if dataclasses.is_dataclass(v) else v for v in value]
        doc[_key(f)] = value
    return doc


def _base(path) -> tuple[dict, dict]:
    """A bundled file as written (small: fast to load) and with every key (its sections'
    defaults, to fill in a section the file leaves out)."""
    doc = yaml.safe_load(path.read_text())
    del doc["kind"], doc["version"]
    return doc, as_document((load_vehicle if doc.get("mass_kg") else load_controller)(path))


SCHEMAS = {"vehicle": (VehicleParams, *_base(vehicle_file("mk_quadro"))),
           "controller": (ControllerParams, *_base(controller_file("design")))}

# Values that other fields must follow for the file to stand (the cross-field physics of each
# schema's __post_init__): set with the number under test.
COMPANIONS = {
    (("mass_kg",), "max"): {("max_rotor_thrust_n",): 500.0},         # 100 kg needs > 245 N a rotor
    (("max_rotor_thrust_n",), "min"): {("mass_kg",): 0.01},          # 4 x 0.05 N lifts 20 g
}
# A bound another field's rule makes unreachable: the one-line refusal that says so.
CROSS = {
    (("disturbance", "rotor_lag", "bounds_s"), 0, "max"): "must be increasing",
    (("disturbance", "rotor_lag", "bounds_s"), 1, "min"): "must be increasing",
    (("disturbance", "thrust_scale_bounds"), 0, "max"): "must bracket 1",
    (("disturbance", "thrust_scale_bounds"), 1, "min"): "must bracket 1",
}
# Vectors whose elements must agree (the inertia's triangle inequality): set whole.
WHOLE = {("inertia_kg_m2",)}


def _set(doc: dict, full: dict, path, value) -> None:
    """``doc[path] = value``, a section ``doc`` leaves out copied whole from ``full`` first."""
    for k in path[:-1]:
        full = full[k]
        if k not in doc:
            doc[k] = copy.deepcopy(full)
        doc = doc[k]
    doc[path[-1]] = value


def _get(doc: dict, path):
    for k in path:
        doc = doc[k]
    return doc


def _text(kind: str, doc: dict) -> str:
    return yaml.dump({"kind": kind, "version": 1, **doc}, Dumper=_DUMPER, sort_keys=False)


def _variant(kind: str, n: Number, index: int | None, value, side: str) -> str:
    """The base file of ``kind`` with ``n`` (element ``index``) at ``value``."""
    _, base, full = SCHEMAS[kind]
    doc = copy.deepcopy(base)
    for path, v in COMPANIONS.get((n.path, side), {}).items():
        _set(doc, full, path, v)
    if n.length is None:
        _set(doc, full, n.path, value)
    else:
        bound = n.lo if side == "min" else n.hi
        vec = [bound] * n.length if n.path in WHOLE else list(_get(full, n.path))
        vec[index] = value
        _set(doc, full, n.path, vec)
    return _text(kind, doc)


def _past(n: Number, side: str):
    if n.is_int:
        return n.lo - 1 if side == "min" else n.hi + 1
    return math.nextafter(n.lo, -math.inf) if side == "min" else math.nextafter(n.hi, math.inf)


def _cases():
    for kind, (schema, *_) in SCHEMAS.items():
        for n in numbers(schema):
            # a vector: its first and last element (the loader checks each alike)
            for index in ([None] if n.length is None else sorted({0, n.length - 1})):
                name = ".".join(n.path) + ("" if index is None else f"[{index}]")
                yield pytest.param(kind, n, index, id=f"{kind}:{name}")


CASES = list(_cases())


def test_every_number_is_found():
    """Negative control of the walk: the nested sections' numbers are among the cases."""
    ids = {c.id for c in CASES}
    assert {"vehicle:mass_kg", "vehicle:inertia_kg_m2[2]", "vehicle:emulator.crash_speed_m_s",
            "vehicle:rate_interface.hover_thrust", "controller:r_input[3]",
            "controller:envelope.maneuver.max_attitude_error_deg", "controller:envelope.recovery.max_recoveries",
            "controller:disturbance.rotor_lag.bounds_s[1]", "controller:speed_governor.max_jerk_m_s3",
            "controller:allocation.max_rotor_thrust_n", "controller:hover_q[11]"} <= ids
    assert len(CASES) > 120


@pytest.mark.parametrize("kind, n, index", CASES)
def test_at_the_bounds_it_loads_and_just_past_it_is_refused_in_one_line(kind, n, index):
    schema = SCHEMAS[kind][0]
    key = ".".join(n.path) + ("" if index is None else f"[{index}]")
    for side, bound in (("min", n.lo), ("max", n.hi)):
        cross = CROSS.get((n.path, index, side))
        text = _variant(kind, n, index, bound, side)
        if cross is None:
            load_text(text, schema, SOURCE, kind=kind)
        else:
            with pytest.raises(ConfigError, match=cross):
                load_text(text, schema, SOURCE, kind=kind)
        past = _past(n, side)
        with pytest.raises(ConfigError) as err:
            load_text(_variant(kind, n, index, past, side), schema, SOURCE, kind=kind)
        msg = str(err.value)
        assert "\n" not in msg and msg.startswith(f"{SOURCE}:"), msg
        assert err.value.key == key, msg
        assert repr(past) in msg and f"range [{n.lo:g}, {n.hi:g}]" in msg, msg


def test_every_bundled_file_loads():
    root = params_dir()
    vehicles = sorted((root / "vehicles").glob("*.yaml"))
    controllers = sorted((root / "controller").glob("*.yaml"))
    assert len(vehicles) >= 5 and len(controllers) >= 8
    for path in vehicles:
        load_vehicle(path)
    for path in controllers:
        load_controller(path)
    for path in maneuver_files():
        load_maneuver(path)
