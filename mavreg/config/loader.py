"""One validating YAML loader for every parameter file of mavreg and firmware_sim.

A schema is a frozen dataclass. Each field's type says what the YAML value must be,
and the field's ``metadata`` may add a range and a unit conversion:

- ``float``, ``int``, ``bool``, ``str``;
- ``tuple[float, ...]`` with ``metadata["length"]`` for a fixed-length vector, and
  ``tuple[tuple[float, ...], ...]`` with ``metadata["item_length"]`` for a list of them;
- a nested schema (another dataclass), or ``tuple[Schema, ...]`` for a list of them;
- ``Optional[T]`` (``T | None``): the key may be left out or be ``null``; a field with a
  default may be left out, one without is required;
- ``metadata["min"]``, ``["max"]``, ``["min_exclusive"]``, ``["max_exclusive"]`` bound numbers (each element of a vector);
- ``metadata["choices"]`` restricts strings, ``metadata["max_length"]`` bounds their length
  (default :data:`MAX_STRING_CHARS`), and ``metadata["max_items"]`` the length of a list;
- ``metadata["deg"] = True`` on a field named ``X_rad`` reads the YAML key ``X_deg``
  and converts degrees to radians (the SI-inside, degrees-in-YAML rule of the conventions);
- ``metadata["union"] = {"line": LineSpec, ...}`` on a field annotated ``object``: the
  value is a mapping with exactly one of those keys, whose value is loaded as that schema;
- ``metadata["was"] = "old_key"``: a renamed key's old spelling is still read, for one
  release, with a one-line :class:`FutureWarning` naming the new one.

Every error is a :class:`ConfigError`: one line naming the file, the line, the key path and
what was expected (a number's whole range too), quoting at most :data:`EXCERPT_CHARS` characters.

Hostile files are refused with bounded work (docs/reliability.md, "Hostile files"): a file
larger than :data:`MAX_FILE_BYTES` is not read past its limit; a file that is not UTF-8 is
refused with the line of its first bad byte; the YAML is composed by
:mod:`mavreg.config.bounded_yaml`, which refuses alias expansion, nesting, merge keys and
duplicate keys beyond its bounds before anything walks the document.
"""
from __future__ import annotations

import dataclasses
import math
import os
import re
import stat
import threading
import types
import typing
import warnings
from pathlib import Path
from typing import Any

import yaml

from .bounded_yaml import Refusal, compose_bounded

__all__ = ["ConfigError", "load_file", "load_text", "MAX_FILE_BYTES", "MAX_STRING_CHARS",
           "EXCERPT_CHARS"]

MAX_FILE_BYTES = 1 << 20
"""1 MiB: the largest parameter file read. The bundled ones are under 4 kB; a maneuver of
1000 waypoints is about 40 kB."""

MAX_STRING_CHARS = 1000
"""Longest string value, unless the schema says otherwise (``metadata["max_length"]``)."""

EXCERPT_CHARS = 60
"""Longest quotation of the file's content in an error message."""

_MESSAGE_CHARS = 400
_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


def _one_line(text: str, limit: int) -> str:
    """``text`` with control characters escaped, cut to ``limit`` characters."""
    text = _CONTROL.sub(lambda m: repr(m.group())[1:-1], text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _excerpt(value: Any) -> str:
    """``repr(value)`` cut to :data:`EXCERPT_CHARS` (a quotation of a hostile file is short)."""
    if isinstance(value, str) and len(value) > EXCERPT_CHARS:
        value = value[:EXCERPT_CHARS]
        return repr(value)[:-1] + "...'"
    text = repr(value)
    return text if len(text) <= EXCERPT_CHARS else text[: EXCERPT_CHARS - 3] + "..."


class ConfigError(ValueError):
    """A parameter file that does not match its schema.

    ``str(err)`` is one line: ``FILE:LINE: KEY: MESSAGE``.
    """

    def __init__(self, source: str, line: int | None, key: str, message: str):
        source, key = _one_line(str(source), 200), _one_line(str(key), 120)
        message = _one_line(str(message), _MESSAGE_CHARS)
        self.source, self.line, self.key, self.message = source, line, key, message
        where = f"{source}:{line}" if line is not None else source
        super().__init__(f"{where}: {key or '<top>'}: {message}" if key else f"{where}: {message}")


def _line(node: yaml.Node | None) -> int | None:
    return None if node is None else node.start_mark.line + 1


def _yaml_key(f: dataclasses.Field) -> str:
    if f.metadata.get("deg"):
        if not f.name.endswith("_rad"):
            raise TypeError(f"field {f.name}: deg=True needs a name ending in _rad")
        return f.name[: -len("_rad")] + "_deg"
    return f.name


class _Ctx:
    def __init__(self, source: str):
        self.source = source

    def fail(self, node: yaml.Node | None, key: str, message: str) -> typing.NoReturn:
        raise ConfigError(self.source, _line(node), key, message)


class _BadScalar(Exception):
    """A scalar PyYAML's safe constructor cannot build (an unknown tag, a 5000-digit int)."""

    def __init__(self, line: int | None, message: str):
        super().__init__(message)
        self.line = line


def _scalar(node: yaml.Node) -> Any:
    """Resolve a scalar node with PyYAML's safe constructor (which then forgets it)."""
    constructor = _constructor()
    try:
        return constructor.construct_object(node, deep=True)
    except (yaml.YAMLError, ValueError, OverflowError, TypeError) as exc:
        why = str(getattr(exc, "problem", None) or exc)
        if "digits" in why:          # Python's bound on int(str): say it without the advice
            why = "a number with too many digits"
        raise _BadScalar(_line(node), why) from None
    finally:
        constructor.constructed_objects.clear()
        constructor.recursive_objects.clear()


_LOCAL = threading.local()


def _constructor() -> yaml.SafeLoader:
    """This thread's scalar constructor (its memo is cleared after each use)."""
    if not hasattr(_LOCAL, "constructor"):
        _LOCAL.constructor = yaml.SafeLoader("")
    return _LOCAL.constructor


def _describe(node: yaml.Node) -> str:
    if not isinstance(node, yaml.ScalarNode):
        return "a mapping" if isinstance(node, yaml.MappingNode) else "a list"
    value = _scalar(node)
    return "null" if value is None else f"{type(value).__name__} {_excerpt(value)}"


def _range(meta: dict) -> str:
    """The field's whole range, `` (range [lo, hi])``, where it has both ends ("" otherwise)."""
    lo, lo_x, hi, hi_x = (meta.get(k) for k in ("min", "min_exclusive", "max", "max_exclusive"))
    low = f"[{lo:g}" if lo is not None and (lo_x is None or lo > lo_x) else lo_x is not None and f"({lo_x:g}"
    high = f"{hi:g}]" if hi is not None and (hi_x is None or hi < hi_x) else hi_x is not None and f"{hi_x:g})"
    return f" (range {low}, {high})" if low and high else ""


def _check_range(ctx: _Ctx, node, key: str, value: float, meta: dict) -> None:
    lo, lo_x, hi, hi_x = (meta.get(k) for k in ("min", "min_exclusive", "max", "max_exclusive"))
    for bad, bound in ((lo_x is not None and not value > lo_x, f"> {lo_x}"),
                       (lo is not None and value < lo, f">= {lo}"),
                       (hi is not None and value > hi, f"<= {hi}"),
                       (hi_x is not None and not value < hi_x, f"< {hi_x}")):
        if bad:
            ctx.fail(node, key, f"expected a value {bound}, got {_excerpt(value)}{_range(meta)}")


_EXPONENT = re.compile(r"[-+]?[0-9]+(\.[0-9]*)?[eE][-+]?[0-9]+")


def _load_number(ctx: _Ctx, node, key: str, tp: type, meta: dict) -> float | int:
    if not isinstance(node, yaml.ScalarNode):
        ctx.fail(node, key, f"expected a number, got {_describe(node)}")
    value = _scalar(node)
    if isinstance(value, str) and node.style is None and _EXPONENT.fullmatch(value):
        value = float(value)      # YAML 1.1 reads 1e-3 (no dot) as a string; unquoted, a number
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        ctx.fail(node, key, f"expected {'an integer' if tp is int else 'a number'}, got {_describe(node)}")
    if tp is int and not isinstance(value, int):
        ctx.fail(node, key, f"expected an integer, got {_excerpt(value)}")
    try:
        finite = math.isfinite(value)
    except OverflowError:        # an integer beyond any float
        finite = False
    if not finite:
        ctx.fail(node, key, f"expected a finite number, got {_excerpt(value)}")
    _check_range(ctx, node, key, value, meta)
    if meta.get("deg"):
        return math.radians(value)
    return float(value) if tp is float else value


def _unwrap_optional(tp: Any) -> tuple[Any, bool]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(tp)) == 2:
            return args[0], True
    return tp, False


def _load_value(ctx: _Ctx, node: yaml.Node, key: str, tp: Any, meta: dict) -> Any:
    tp, optional = _unwrap_optional(tp)
    if optional and isinstance(node, yaml.ScalarNode) and _scalar(node) is None:
        return None
    if "union" in meta:
        return _load_union(ctx, node, key, meta["union"])
    if dataclasses.is_dataclass(tp):
        return _load_schema(ctx, node, tp, key)
    if tp in (float, int):
        return _load_number(ctx, node, key, tp, meta)
    if tp is bool:
        value = _scalar(node) if isinstance(node, yaml.ScalarNode) else None
        if not isinstance(value, bool):
            ctx.fail(node, key, f"expected true or false, got {_describe(node)}")
        return value
    if tp is str:
        value = _scalar(node) if isinstance(node, yaml.ScalarNode) else None
        if not isinstance(value, str):
            ctx.fail(node, key, f"expected a string, got {_describe(node)}")
        choices = meta.get("choices")
        if choices is not None and value not in choices:
            ctx.fail(node, key, f"expected one of {', '.join(map(str, choices))}, got {_excerpt(value)}")
        longest = meta.get("max_length", MAX_STRING_CHARS)
        if len(value) > longest:
            ctx.fail(node, key, f"expected at most {longest} characters, got {len(value)}")
        return value
    if typing.get_origin(tp) is tuple:
        return _load_tuple(ctx, node, key, tp, meta)
    raise TypeError(f"unsupported schema type {tp!r} for {key}")


def _load_tuple(ctx: _Ctx, node, key: str, tp: Any, meta: dict) -> tuple:
    (elem_tp, *rest) = typing.get_args(tp)
    if not isinstance(node, yaml.SequenceNode):
        ctx.fail(node, key, f"expected a list, got {_describe(node)}")
    n = meta.get("length")
    if n is not None and len(node.value) != n:
        ctx.fail(node, key, f"expected a list of {n} values, got {len(node.value)}")
    lo = meta.get("min_items", 0)
    if len(node.value) < lo:
        ctx.fail(node, key, f"expected at least {lo} items, got {len(node.value)}")
    hi = meta.get("max_items")
    if hi is not None and len(node.value) > hi:
        ctx.fail(node, key, f"expected at most {hi} items, got {len(node.value)}")
    elem_meta = {k: v for k, v in meta.items()
                 if k not in ("length", "min_items", "max_items", "item_length")}
    if "item_length" in meta:
        elem_meta["length"] = meta["item_length"]
    return tuple(
        _load_value(ctx, item, f"{key}[{i}]", elem_tp, elem_meta) for i, item in enumerate(node.value)
    )


def _load_union(ctx: _Ctx, node, key: str, kinds: dict[str, type]) -> Any:
    if not isinstance(node, yaml.MappingNode) or len(node.value) != 1:
        ctx.fail(node, key, f"expected a mapping with exactly one of: {', '.join(kinds)}")
    knode, vnode = node.value[0]
    name = _scalar(knode)
    if not isinstance(name, str) or name not in kinds:
        ctx.fail(knode, f"{key}.{_one_line(str(name), 40)}",
                 f"unknown kind; expected one of: {', '.join(kinds)}")
    return _load_schema(ctx, vnode, kinds[name], f"{key}.{name}")


def _load_schema(ctx: _Ctx, node: yaml.Node, schema: type, prefix: str = "") -> Any:
    if not isinstance(node, yaml.MappingNode):
        ctx.fail(node, prefix, f"expected a mapping, got {_describe(node)}")
    hints = typing.get_type_hints(schema)
    fields = {_yaml_key(f): f for f in dataclasses.fields(schema)}
    renamed = {f.metadata["was"]: _yaml_key(f) for f in dataclasses.fields(schema) if "was" in f.metadata}
    seen: dict[str, tuple[yaml.Node, yaml.Node]] = {}
    for knode, vnode in node.value:
        name = _scalar(knode)
        shown = _one_line(str(name), 40)
        path = f"{prefix}.{shown}" if prefix else shown
        if isinstance(name, str) and name in renamed:      # an old spelling, read for one release
            warnings.warn(f"{ctx.source}: line {_line(knode)}: {path} is deprecated and goes in the next "
                          f"release; write {renamed[name]}", FutureWarning, stacklevel=2)
            name = renamed[name]
        if not isinstance(name, str) or name not in fields:
            ctx.fail(knode, path, f"unknown key; expected one of: {', '.join(fields)}")
        if name in seen:
            ctx.fail(knode, path, "duplicate key")
        seen[name] = (knode, vnode)
    values = {}
    for yk, f in fields.items():
        path = f"{prefix}.{yk}" if prefix else yk
        if yk not in seen:
            has_default = f.default is not dataclasses.MISSING or f.default_factory is not dataclasses.MISSING
            if not has_default:
                ctx.fail(node, path, "missing required key")
            continue
        values[f.name] = _load_value(ctx, seen[yk][1], path, hints[f.name], dict(f.metadata))
    try:
        obj = schema(**values)
    except ValueError as exc:  # cross-field checks in __post_init__
        ctx.fail(node, prefix, str(exc))
    return obj


def load_text(text: str, schema: type, source: str = "<string>", kind: str | None = None) -> Any:
    """Parse YAML ``text`` and load it as ``schema``.

    If ``kind`` is given, the document must carry ``kind: <kind>`` and ``version: 1``;
    both keys are checked and removed before the schema sees the mapping. Text longer than
    :data:`MAX_FILE_BYTES` (UTF-8) is refused before it is parsed.
    """
    if len(text) > MAX_FILE_BYTES or (4 * len(text) > MAX_FILE_BYTES
                                      and len(text.encode("utf-8", "replace")) > MAX_FILE_BYTES):
        raise ConfigError(source, None, "", f"larger than {MAX_FILE_BYTES} bytes (the limit of "
                                            "a parameter file)")
    try:
        node = compose_bounded(text)
        if node is None:
            raise ConfigError(source, None, "", "empty file")
        ctx = _Ctx(source)
        if kind is not None:
            node = _check_header(ctx, node, kind)
        return _load_schema(ctx, node, schema)
    except Refusal as exc:
        raise ConfigError(source, exc.line, "", exc.message) from None
    except _BadScalar as exc:
        raise ConfigError(source, exc.line, "", f"cannot read this value: {exc}") from None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        raise ConfigError(source, line, "", f"not valid YAML: {exc.problem or exc}") from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, exc.position) + 1
        ch = exc.character
        shown = f"#x{ch:04x}" if isinstance(ch, int) else _excerpt(ch)
        raise ConfigError(source, line, "", f"not valid YAML: character {shown} is not allowed") from None
    except yaml.YAMLError as exc:
        raise ConfigError(source, None, "", f"not valid YAML: {exc}") from None
    except RecursionError:       # the composer's depth bound should make this unreachable
        raise ConfigError(source, None, "", "nested too deeply") from None


def _check_header(ctx: _Ctx, node: yaml.Node, kind: str) -> yaml.MappingNode:
    if not isinstance(node, yaml.MappingNode):
        ctx.fail(node, "", f"expected a mapping starting with 'kind: {kind}'")
    header, rest = {}, []
    for knode, vnode in node.value:
        if _scalar(knode) in ("kind", "version"):
            header[_scalar(knode)] = vnode
        else:
            rest.append((knode, vnode))
    for key, want in (("kind", kind), ("version", 1)):
        if key not in header:
            ctx.fail(node, key, f"missing required key (expected '{key}: {want}')")
        got = _scalar(header[key]) if isinstance(header[key], yaml.ScalarNode) else None
        if got != want or isinstance(got, bool):
            ctx.fail(header[key], key, f"expected {want!r}, got {_describe(header[key])}")
    return yaml.MappingNode(node.tag, rest, node.start_mark, node.end_mark, node.flow_style)


def load_file(path: str | Path, schema: type, kind: str | None = None) -> Any:
    """Read and load a YAML parameter file. Errors name ``path`` as given.

    At most :data:`MAX_FILE_BYTES` + 1 bytes are read, so a huge file or a device
    (``/dev/zero``) is refused at once, and a named pipe nobody writes to is an empty file;
    the bytes must be UTF-8.
    """
    source = str(path)
    try:
        # Non-blocking open: a FIFO without a writer reads as empty instead of hanging here.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb") as f:
            if _regular_size(f) > MAX_FILE_BYTES:
                data = b"x" * (MAX_FILE_BYTES + 1)
            else:
                data = f.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ConfigError(source, None, "", f"cannot read file: {exc.strerror or exc}") from None
    if len(data) > MAX_FILE_BYTES:
        raise ConfigError(source, None, "", f"larger than {MAX_FILE_BYTES} bytes (the limit of "
                                            "a parameter file)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ConfigError(source, line, "", f"not UTF-8 text (byte 0x{data[exc.start]:02x} at "
                                            f"offset {exc.start})") from None
    return load_text(text, schema, source, kind)


def _regular_size(f) -> int:
    """The size of a regular file (0 for a device or a pipe, which are read up to the limit)."""
    st = os.fstat(f.fileno())
    return st.st_size if stat.S_ISREG(st.st_mode) else 0
