"""The hostile corpus: ``python tests/data/hostile/generate.py`` writes this directory's files
from the barrel roll. Each is small; the big cases (a 100 MB file, /dev/zero, 100 000
waypoints, 100 000-deep nesting, --laps 100, riccati_step_s 1e-9) and the barrel roll with
each required key missing are made at test time by :func:`big_cases` and
:func:`missing_key_cases` (tests/unit/test_hostile_files.py, benchmarks/hostile_files.py).
Every case must give ``mavreg plan`` exit 2 and one line on stderr."""
from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import time
import typing
from pathlib import Path

import yaml

from mavreg.config.paths import DESIGN_CONTROLLER, maneuver_file

HERE = Path(__file__).resolve().parent
BARREL = maneuver_file("barrel_roll").read_text()
HEAD = "kind: maneuver\nversion: 1\n"


def _sub(old: str, new: str) -> str:
    assert old in BARREL, old
    return BARREL.replace(old, new, 1)


def _laughs(levels: int) -> str:
    """Anchors a..: each a list of ten aliases of the one before (10**levels leaves)."""
    out = ["l0: &l0 [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for i in range(1, levels):
        out.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 10) + "]")
    return "\n".join(out) + "\n"


def corpus() -> dict[str, str | bytes]:
    laughs = _laughs(10)
    nested_anchors = "".join(f"{' ' * 2 * i}a{i}: &a{i}\n" for i in range(10))
    files: dict[str, str | bytes] = {
        # alias bombs: ten levels of ten (10**10 leaves), in a value, as a key, in the header
        "alias_bomb_kind.yaml": HEAD.replace("kind: maneuver", "kind: &k0 [lol, lol]") + laughs
        + "x: *l9\n",
        "alias_bomb_value.yaml": laughs.replace("l", "q") + _sub("name: barrel_roll", "name: *q9"),
        "alias_bomb_key.yaml": laughs + "? *l9\n: 1\n" + BARREL,
        "alias_bomb_segments.yaml": laughs + _sub("segments:\n", "segments: *l9\nold_segments:\n"),
        "alias_cycle.yaml": _sub("name: barrel_roll", "name: &c [*c]"),
        "alias_undefined.yaml": _sub("name: barrel_roll", "name: *nowhere"),
        "anchors_nested_mapping.yaml": HEAD + nested_anchors,
        # nesting
        "deep_list.yaml": HEAD + "name: " + "[" * 2000 + "]" * 2000 + "\n",
        "deep_mapping.yaml": HEAD + "name: " + "{a: " * 500 + "1" + "}" * 500 + "\n",
        "deep_block.yaml": HEAD + "".join(f"{' ' * i}k{i}:\n" for i in range(60)) + " " * 60 + "v\n",
        # YAML features the loader does not take
        "merge_key.yaml": _sub("limits:\n", "base: &b {min_speed_m_s: 0.2}\nlimits:\n  <<: *b\n"),
        "merge_key_top.yaml": "<<: {name: x}\n" + BARREL,
        "python_tag.yaml": _sub("initial_m_s: 0.5", "initial_m_s: !!python/object/apply:os.system [true]"),
        "binary_tag.yaml": _sub("name: barrel_roll", "name: !!binary aGVsbG8="),
        "set_tag.yaml": _sub("name: barrel_roll", "name: !!set {a, b}"),
        "two_documents.yaml": BARREL + "---\n" + BARREL,
        "empty.yaml": "",
        "only_comment.yaml": "# nothing here\n",
        "duplicate_key.yaml": _sub("name: barrel_roll", "name: barrel_roll\nname: again"),
        "duplicate_kind.yaml": "kind: maneuver\n" + BARREL,
        "complex_key.yaml": "? [a, b]\n: 1\n" + BARREL,
        "tab_indent.yaml": _sub("  position_m:", "\tposition_m:"),
        "not_yaml.yaml": "{{{{ ]]]] : : :\n",
        "unknown_key.yaml": _sub("limits:", "limitz:"),
        "newline_in_key.yaml": _sub("limits:", '"lim\\nits":'),
        "long_key.yaml": BARREL + "k" * 5000 + ": 1\n",
        "long_name.yaml": _sub("name: barrel_roll", "name: " + "x" * 5000),
        "long_description.yaml": _sub("description: Paper", "description: " + "y" * 5000),
        "top_is_list.yaml": "- 1\n- 2\n",
        "top_is_scalar.yaml": "just a string\n",
        "wrong_kind.yaml": BARREL.replace("kind: maneuver", "kind: vehicle"),
        "wrong_version.yaml": BARREL.replace("version: 1", "version: 2"),
        # bytes
        "non_utf8_latin1.yaml": _sub("Paper barrel", "Pap\xe9r barrel").encode("latin-1"),
        "non_utf8_invalid.yaml": BARREL.encode() + b"\xff\xfe\xfd\n",
        "utf16.yaml": BARREL.encode("utf-16"),
        "nul_byte.yaml": BARREL + "\x00\n",
        "control_char.yaml": _sub("name: barrel_roll", "name: bar\x07rel"),
        # wrong types
        "type_name_list.yaml": _sub("name: barrel_roll", "name: [1, 2]"),
        "type_start_string.yaml": BARREL.replace("start:\n  position_m: [0.0, 16.0, -3.0]", "start: here\nx:\n  position_m: [0.0, 16.0, -3.0]"),
        "type_segments_mapping.yaml": _sub("segments:\n", "segments: {a: 1}\nold:\n"),
        "type_position_string.yaml": _sub("position_m: [0.0, 16.0, -3.0]", "position_m: abc"),
        "type_position_two.yaml": _sub("position_m: [0.0, 16.0, -3.0]", "position_m: [0.0, 16.0]"),
        "type_heading_bool.yaml": _sub("heading_deg: 270", "heading_deg: true"),
        "type_heading_quoted.yaml": _sub("heading_deg: 270", 'heading_deg: "270"'),
        "type_laps_float.yaml": _sub("count: 1", "count: 1.5"),
        "type_changes_int.yaml": _sub("  changes:\n    - {segment: run_up", "  changes: 3\n  old:\n    - {segment: run_up"),
        "type_line_list.yaml": _sub("line: {length_m: 18.0}", "line: [18.0]"),
        "type_length_null.yaml": _sub("line: {length_m: 18.0}", "line: {length_m: null}"),
        "type_length_date.yaml": _sub("line: {length_m: 18.0}", "line: {length_m: 2024-01-01}"),
        "type_two_shapes.yaml": _sub("line: {length_m: 18.0}", "line: {length_m: 18.0}\n    arc: {radius_m: 1, angle_deg: 90}"),
        "type_union_unknown.yaml": _sub("line: {length_m: 18.0}", "spiral: {length_m: 18.0}"),
        # NaN and infinities
        "nan_speed.yaml": _sub("initial_m_s: 0.5", "initial_m_s: .nan"),
        "inf_length.yaml": _sub("length_m: 18.0", "length_m: .inf"),
        "neg_inf_position.yaml": _sub("position_m: [0.0, 16.0, -3.0]", "position_m: [-.inf, 16.0, -3.0]"),
        "nan_yaw.yaml": _sub("initial_deg: 0", "initial_deg: .NaN"),
        "inf_radius.yaml": _sub("radius_m: 1.5", "radius_m: .Inf"),
        "overflow_float.yaml": _sub("length_m: 18.0", "length_m: 1e400"),
        # huge numbers
        "huge_position.yaml": _sub("position_m: [0.0, 16.0, -3.0]", "position_m: [1e300, 0, -3]"),
        "huge_length_1e4.yaml": _sub("length_m: 18.0", "length_m: 1e4"),
        "huge_length_1e9.yaml": _sub("length_m: 18.0", "length_m: 1e9"),
        "huge_radius.yaml": _sub("radius_m: 1.5", "radius_m: 1e6"),
        "huge_angle.yaml": _sub("angle_deg: 400", "angle_deg: 1e9"),
        "huge_speed.yaml": _sub("to_m_s: 8.0", "to_m_s: 1e6"),
        "huge_laps.yaml": _sub("count: 1", "count: 1000000"),
        "huge_int_digits.yaml": _sub("count: 1", "count: " + "9" * 5000),
        "huge_int_as_float.yaml": _sub("initial_m_s: 0.5", "initial_m_s: " + "9" * 400),
        "huge_blend.yaml": _sub("blend_m: 3.0", "blend_m: 1e12"),
        "huge_offset.yaml": _sub("offset_m: 0.0, length_m: 10.0", "offset_m: 500, length_m: 10.0"),
        "offset_end_beyond.yaml": _sub("anchor: end, offset_m: 1.5", "anchor: end, offset_m: 50"),
        "long_line_over_budget.yaml": _sub("length_m: 18.0", "length_m: 1000"),
        "many_laps_over_budget.yaml": _sub("count: 1", "count: 100"),
        "crawl_over_budget.yaml": _sub("to_m_s: 8.0", "to_m_s: 0.02"),
        # tiny numbers
        "tiny_speed.yaml": _sub("initial_m_s: 0.5", "initial_m_s: 1e-300"),
        "zero_radius.yaml": _sub("radius_m: 1.5", "radius_m: 0"),
        "negative_length.yaml": _sub("length_m: 18.0", "length_m: -18"),
        "tiny_change_length.yaml": _sub("length_m: 10.0, to_m_s: 8.0", "length_m: 1e-300, to_m_s: 8.0"),
        "denormal_speed.yaml": _sub("to_m_s: 8.0", "to_m_s: 5e-324"),
        # enormous arrays (within the size limit)
        "waypoints_1001.yaml": _sub("line: {length_m: 18.0}", "waypoints: {points_m: ["
                                    + ", ".join(f"[{i * 0.1:.1f}, 0, 0]" for i in range(1, 1002)) + "]}"),
        "waypoints_far.yaml": _sub("line: {length_m: 18.0}", "waypoints: {points_m: ["
                                   + ", ".join(f"[{(-1) ** i * 900}, {i}, 0]" for i in range(1, 40)) + "]}"),
        "segments_101.yaml": _sub("segments:\n", "segments:\n" + "".join(
            f"  - {{name: s{i}, line: {{length_m: 0.1}}}}\n" for i in range(101))),
        "changes_flood.yaml": _sub("  changes:\n", "  changes:\n" + "".join(
            f"    - {{segment: run_up, offset_m: {i * 0.01:.2f}, length_m: 0.01, to_m_s: 1}}\n"
            for i in range(150))),
        "list_of_10k_numbers.yaml": _sub("position_m: [0.0, 16.0, -3.0]",
                                         "position_m: [" + ",".join("1" for _ in range(10001)) + "]"),
    }
    return files


def _required_paths(obj, schema, path=()) -> list[tuple]:
    """Key paths in ``obj`` (the YAML as loaded) whose removal the schema refuses: fields
    without a default, and a segment's shape (it needs exactly one)."""
    hints = typing.get_type_hints(schema)
    out = []
    for f in dataclasses.fields(schema):
        key = f.name[:-4] + "_deg" if f.metadata.get("deg") else f.name
        if key not in obj:
            continue
        shape = schema.__name__ == "SegmentSpec" and key in ("line", "arc", "helix", "waypoints")
        if (f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING) or shape:
            out.append(path + (key,))
        tp = hints[f.name]
        args = [a for a in typing.get_args(tp) if a is not type(None) and a is not Ellipsis]
        inner = tp if dataclasses.is_dataclass(tp) else (args[0] if args else None)
        if not dataclasses.is_dataclass(inner):
            continue
        if isinstance(obj[key], list):
            for i, item in enumerate(obj[key]):
                out += _required_paths(item, inner, path + (key, i))
        elif isinstance(obj[key], dict):
            out += _required_paths(obj[key], inner, path + (key,))
    return out


def required_key_paths() -> list[tuple]:
    """Every key of the barrel roll the loader requires, as a path (``("segments", 1, "arc",
    "radius_m")``), the header's ``kind`` and ``version`` first."""
    from mavreg.config.maneuver import ManeuverSpec
    data = yaml.safe_load(BARREL)
    body = {k: v for k, v in data.items() if k not in ("kind", "version")}
    return [("kind",), ("version",)] + _required_paths(body, ManeuverSpec)


def missing_key_cases() -> dict[str, str]:
    """The barrel roll without each required key in turn: name -> YAML text."""
    out = {}
    for key_path in required_key_paths():
        data = yaml.safe_load(BARREL)
        parent = data
        for k in key_path[:-1]:
            parent = parent[k]
        del parent[key_path[-1]]
        out["missing " + ".".join(map(str, key_path))] = yaml.safe_dump(data, sort_keys=False)
    return out


def _waypoints(n: int, compact: bool) -> str:
    """The barrel roll with its run-up replaced by ``n`` distinct waypoints."""
    if compact:
        pts = ",".join(f"[{i % 1000},{i // 1000},0]" for i in range(1, n + 1))
    else:
        pts = ",\n        ".join(f"[{(i % 100) * 0.5 + 0.5}, {i // 100 * 0.5}, 0]" for i in range(n))
    return _sub("line: {length_m: 18.0}", f"waypoints: {{points_m: [{pts}]}}")


def big_cases(tmp: Path) -> dict[str, list[str]]:
    """The big cases, written into ``tmp``: name -> arguments of ``mavreg plan``."""
    barrel = str(maneuver_file("barrel_roll"))
    big = tmp / "100MB.yaml"
    with open(big, "wb") as f:
        f.write(BARREL.encode())
        f.truncate(100 * 2 ** 20)                 # sparse: 100 MB without writing them
    files = {
        "deep100k.yaml": "kind: maneuver\nversion: 1\nname: " + "[" * 100_000 + "]" * 100_000 + "\n",
        "waypoints100k.yaml": _waypoints(100_000, compact=False),
        "waypoints60k_compact.yaml": _waypoints(60_000, compact=True),
        "step1e-9.yaml": DESIGN_CONTROLLER.read_text().replace(
            "riccati_step_s: 0.002", "riccati_step_s: 1e-9"),
        "step1e-4.yaml": DESIGN_CONTROLLER.read_text().replace(
            "riccati_step_s: 0.002", "riccati_step_s: 1e-4"),
    }
    for name, text in files.items():
        (tmp / name).write_text(text)
    return {
        "startup (a missing file)": [str(tmp / "no_such_file.yaml")],
        "alias bomb (kind:)": [str(HERE / "alias_bomb_kind.yaml")],
        "/dev/zero": ["/dev/zero"],
        "100 MB file": [str(big)],
        "100 000-deep nesting": [str(tmp / "deep100k.yaml")],
        "100 000 waypoints (2 MB)": [str(tmp / "waypoints100k.yaml")],
        "60 000 waypoints (compact, under 1 MiB)": [str(tmp / "waypoints60k_compact.yaml")],
        "--laps 100": [barrel, "--laps", "100"],
        "riccati_step_s 1e-9": [barrel, "--controller", str(tmp / "step1e-9.yaml")],
        "riccati_step_s 1e-4 (budget)": [barrel, "--controller", str(tmp / "step1e-4.yaml")],
    }


_WRAPPER = ("import resource, subprocess, sys; rc = subprocess.call(sys.argv[2:]); "
            "open(sys.argv[1], 'w').write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)); "
            "sys.exit(rc if rc >= 0 else 128 - rc)")
"""Runs a command and writes its peak RSS (kB). A process's ``ru_maxrss`` starts from the
high-water mark of whatever it was forked from (Linux keeps it across exec, and a vfork
borrows the parent's memory), so a child of a large test process would report the test's
size; the grandchild of this small wrapper reports its own."""


def run_measured(args: list[str], tmp: Path) -> tuple[int, str, float, float]:
    """``mavreg plan ARGS`` in a subprocess without the plan cache: (status, stderr, seconds,
    peak RSS in MB of that process)."""
    err_file, rss_file = tmp / "stderr.txt", tmp / "maxrss.txt"
    cmd = [sys.executable, "-c", _WRAPPER, str(rss_file),
           sys.executable, "-m", "mavreg.cli.main", "plan", *args]
    with open(err_file, "wb") as err:
        t0 = time.perf_counter()
        rc = subprocess.call(cmd, stdout=subprocess.DEVNULL, stderr=err,
                             env={**os.environ, "MAVREG_PLAN_CACHE": "off"})
        seconds = time.perf_counter() - t0
    return rc, err_file.read_text(errors="replace"), seconds, int(rss_file.read_text()) / 1024


def main() -> None:
    for old in HERE.glob("*.yaml"):
        old.unlink()
    for name, content in corpus().items():
        data = content if isinstance(content, bytes) else content.encode()
        assert len(data) < 64 * 1024, name
        (HERE / name).write_bytes(data)


if __name__ == "__main__":
    main()
