"""The loader's bounds on hostile YAML (mavreg.config.bounded_yaml, mavreg.config.loader):
each is checked at its edge, with the legitimate side loading."""
from __future__ import annotations

import pytest

from mavreg.config.paths import maneuver_file
from mavreg.config import loader
from mavreg.config.bounded_yaml import MAX_DEPTH, MAX_NODES, Refusal, compose_bounded
from mavreg.config.loader import EXCERPT_CHARS, ConfigError, load_file
from mavreg.config.maneuver import ManeuverSpec, load_maneuver_text

BARREL = maneuver_file("barrel_roll").read_text()


def _nested(levels: int) -> str:
    return "[" * (levels - 1) + "1" + "]" * (levels - 1)


def test_depth_at_the_bound_composes_and_one_more_is_refused():
    compose_bounded(_nested(MAX_DEPTH))
    with pytest.raises(Refusal, match=f"nested deeper than {MAX_DEPTH}"):
        compose_bounded(_nested(MAX_DEPTH + 1))


def test_aliases_count_as_what_they_repeat():
    """A list of n nodes repeated k times by aliases: refused once n * k passes the budget,
    though the composed graph itself stays n nodes."""
    n = MAX_NODES // 4
    block = "a: &a [" + ",".join(["1"] * (n - 1)) + "]\n"
    compose_bounded(block + "b: [*a, *a]\n")
    with pytest.raises(Refusal, match=f"more than {MAX_NODES} nodes at alias \\*a"):
        compose_bounded(block + "b: [*a, *a, *a, *a]\n")


def test_aliases_within_the_budget_still_load():
    text = BARREL.replace("initial_m_s: 0.5", "initial_m_s: &slow 0.5").replace(
        "length_m: 10.0, to_m_s: 0.5", "length_m: 10.0, to_m_s: *slow")
    spec = load_maneuver_text(text, "aliases")
    assert spec.speed.changes[1].to_m_s == spec.speed.initial_m_s == 0.5


def test_a_billion_laughs_is_refused_at_the_alias_that_passes_the_budget():
    levels = ["l0: &l0 [" + ",".join(["x"] * 10) + "]"] + [
        f"l{i}: &l{i} [" + ",".join([f"*l{i - 1}"] * 10) + "]" for i in range(1, 10)]
    with pytest.raises(ConfigError, match=r"^bomb:\d: more than \d+ nodes at alias \*l\d"):
        load_maneuver_text("\n".join(levels) + "\n", "bomb")


def test_quotations_are_short_and_one_line():
    with pytest.raises(ConfigError) as err:
        load_maneuver_text(BARREL.replace("heading_deg: 270", "heading_deg: '" + "9" * 5000 + "'"), "q")
    msg = str(err.value)
    assert "\n" not in msg and len(msg) < 40 + 2 * EXCERPT_CHARS
    with pytest.raises(ConfigError) as err:
        load_maneuver_text(BARREL.replace("limits:", '"a\\nb\\u2028c":'), "nl")
    assert "\n" not in str(err.value) and "\u2028" not in str(err.value) and "a\\nb" in str(err.value)


def test_non_utf8_names_the_line_of_the_first_bad_byte(tmp_path):
    f = tmp_path / "latin1.yaml"
    f.write_bytes(BARREL.encode().replace(b"barrel_roll\n", b"barr\xe9l_roll\n"))
    with pytest.raises(ConfigError, match=r"latin1.yaml:16: not UTF-8 text \(byte 0xe9"):
        load_file(f, ManeuverSpec, kind="maneuver")


def test_a_file_is_read_only_up_to_the_limit(tmp_path, monkeypatch):
    """A file one byte over the limit is refused; a pipe or a device is read up to the limit
    and no further (monkeypatched small limit: the check is the same at 1 MiB)."""
    monkeypatch.setattr(loader, "MAX_FILE_BYTES", 64)
    f = tmp_path / "f.yaml"
    f.write_text("a: " + "x" * 62)
    with pytest.raises(ConfigError, match="larger than 64 bytes"):
        load_file(f, ManeuverSpec)
    with pytest.raises(ConfigError, match="larger than 64 bytes"):
        load_file("/dev/zero", ManeuverSpec)
    with pytest.raises(ConfigError, match="larger than 64 bytes"):
        load_maneuver_text("x" * 65)


def test_a_named_pipe_without_a_writer_does_not_hang(tmp_path):
    import os
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match="fifo.yaml: empty file"):
        load_file(fifo, ManeuverSpec, kind="maneuver")


def test_the_scalar_constructor_forgets_what_it_built():
    """PyYAML's constructor memoizes every node it builds; the loader's shared one must not
    keep the nodes of every file a long-running daemon loads."""
    load_maneuver_text(BARREL, "once")
    c = loader._constructor()
    assert not c.constructed_objects and not c.recursive_objects


@pytest.mark.parametrize("text, match", [
    ("a: 1\n<<: {b: 2}\n", "merge keys"),
    ("a: 1\na: 2\n", "duplicate key 'a'"),
    ("? [1, 2]\n: 3\n", "a key must be a plain name"),
    ("a: &x [*x]\n", "refers to a node that contains it"),
])
def test_yaml_features_the_loader_refuses(text, match):
    with pytest.raises(Refusal, match=match):
        compose_bounded(text)


def test_physics_bounds_of_the_maneuver_file():
    for old, new, match in [
        ("position_m: [0.0, 16.0, -3.0]", "position_m: [1e300, 0, -3]", r"start.position_m\[0\]: expected a value <= 1000"),
        ("length_m: 18.0", "length_m: 1e4", "length_m: expected a value <= 1000"),
        ("radius_m: 1.5", "radius_m: 1e-9", "radius_m: expected a value >= 0.001"),
        ("initial_m_s: 0.5", "initial_m_s: 1e-9", "initial_m_s: expected a value >= 0.01"),
        ("angle_deg: 400", "angle_deg: 1e6", "angle_deg: expected a value <= 3600"),
    ]:
        with pytest.raises(ConfigError, match=match):
            load_maneuver_text(BARREL.replace(old, new), "x")
