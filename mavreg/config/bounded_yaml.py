"""A YAML composer that bounds the work a hostile file can cause.

PyYAML composes an alias as a second reference to the anchored node, so the node graph of a
"billion laughs" file is small; it is whoever walks the graph afterwards (a constructor, or
:mod:`mavreg.config.loader`) that does the exponential work. :class:`BoundedLoader` counts
while it composes, and refuses before anything walks the graph:

- more than :data:`MAX_NODES` nodes, every alias counting as the whole subtree it repeats;
- nesting deeper than :data:`MAX_DEPTH` (so that no walker can recurse without bound);
- an alias to a node still being composed (a cycle: ``&a [*a]``);
- a mapping key that is not a scalar, a duplicate key, and a merge key (``<<``), which the
  loader does not support: a parameter file writes its keys out.

Each refusal is a :class:`Refusal` carrying the 1-based line and a one-line message.
"""
from __future__ import annotations

import yaml

__all__ = ["BoundedLoader", "Refusal", "MAX_NODES", "MAX_DEPTH", "compose_bounded"]

MAX_NODES = 10_000
"""Nodes in a document, aliases expanded. A maneuver of 1000 waypoints (the most a waypoint
segment takes) is about 4 000; the bundled parameter files are under 400. Composing costs
about 30 us a node (pure-Python PyYAML), so refusing at the bound takes 0.3 s."""

MAX_DEPTH = 32
"""Levels of nesting. The deepest schema (a controller's envelope phases) needs 4."""

_MERGE_TAG = "tag:yaml.org,2002:merge"


class Refusal(Exception):
    """A document the bounded composer will not compose: ``line`` (1-based) and why."""

    def __init__(self, line: int | None, message: str):
        super().__init__(message)
        self.line = line
        self.message = message


def _line(mark) -> int | None:
    return None if mark is None else mark.line + 1


class BoundedLoader(yaml.SafeLoader):
    """A :class:`yaml.SafeLoader` whose composer counts nodes and depth (module docstring)."""

    def __init__(self, stream):
        super().__init__(stream)
        self._nodes = 0
        self._depth = 0
        self._sizes: dict[str, int] = {}      # anchor -> nodes of its subtree, aliases expanded
        self._open: set[str] = set()          # anchors whose node is being composed

    def _count(self, n: int, mark, what: str) -> None:
        self._nodes += n
        if self._nodes > MAX_NODES:
            raise Refusal(_line(mark), f"more than {MAX_NODES} nodes at {what} (an alias counts "
                                       "as the nodes it repeats)")

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            if event.anchor in self._open:
                raise Refusal(_line(event.start_mark),
                              f"alias *{event.anchor[:40]} refers to a node that contains it")
            self._count(self._sizes.get(event.anchor, 1), event.start_mark,
                        f"alias *{event.anchor[:40]}")
            return super().compose_node(parent, index)
        event = self.peek_event()
        if self._depth >= MAX_DEPTH:
            raise Refusal(_line(event.start_mark), f"nested deeper than {MAX_DEPTH} levels")
        anchor = event.anchor
        before = self._nodes
        self._count(1, event.start_mark, "this value")
        self._depth += 1
        if anchor is not None:
            self._open.add(anchor)
        node = super().compose_node(parent, index)
        self._depth -= 1
        if anchor is not None:
            self._open.discard(anchor)
            self._sizes[anchor] = self._nodes - before
        return node

    def compose_mapping_node(self, anchor):
        node = super().compose_mapping_node(anchor)
        seen = set()
        for knode, _ in node.value:
            if not isinstance(knode, yaml.ScalarNode):
                raise Refusal(_line(knode.start_mark), "a key must be a plain name, "
                                                       "not a list or a mapping")
            if knode.tag == _MERGE_TAG:
                raise Refusal(_line(knode.start_mark), "merge keys (<<) are not supported; "
                                                       "write the keys out")
            if knode.value in seen:
                raise Refusal(_line(knode.start_mark), f"duplicate key {_short(knode.value)}")
            seen.add(knode.value)
        return node


def _short(text: str, limit: int = 40) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "...")


def compose_bounded(text: str) -> yaml.Node | None:
    """The single document of ``text`` as a node graph, within the bounds above.

    Raises
    ------
    Refusal
        The document breaks one of the bounds.
    yaml.YAMLError
        The text is not YAML.
    """
    loader = BoundedLoader(text)
    try:
        return loader.get_single_node()
    finally:
        loader.dispose()
