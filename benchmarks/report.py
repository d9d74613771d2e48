"""The benchmarks' table: figure, value, baseline, ratio, target, met?, unit; and the notes.

Every section returns a flat dict of figure records (:func:`benchmarks.io_helpers.figure`);
:func:`format_table` prints any number of them as one table, :func:`standalone` is the
``main`` of a section run alone (``--quick``, ``--json FILE``).
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Callable

__all__ = ["format_table", "format_notes", "format_targets", "standalone", "fmt"]

_HEAD = ("figure", "value", "baseline", "ratio", "target", "met?", "unit")


def fmt(v) -> str:
    """A number in 3-4 significant digits, thousands separated; '-' for none."""
    if v is None:
        return "-"
    a = abs(v)
    if a >= 1000:
        return f"{v:,.0f}"
    if a >= 100:
        return f"{v:.0f}"
    if a >= 10:
        return f"{v:.1f}"
    if a >= 1:
        return f"{v:.2f}"
    return f"{v:.3g}"


def _met(f: dict) -> str:
    return {True: "yes", False: "NO", None: ""}[f.get("met")]


def format_table(figs: dict) -> str:
    """One aligned table of the figures, in their order."""
    rows = [_HEAD] + [(k, fmt(f["value"]), fmt(f["baseline"]),
                       "" if f["ratio"] is None else f"{f['ratio']:.2f}x", fmt(f["target"]) if f["target"] else "",
                       _met(f), f["unit"]) for k, f in figs.items()]
    widths = [max(len(r[i]) for r in rows) for i in range(len(_HEAD))]
    lines = []
    for n, r in enumerate(rows):
        cells = [r[0].ljust(widths[0])] + [c.rjust(w) for c, w in zip(r[1:-1], widths[1:-1])] + [r[-1]]
        lines.append("  ".join(cells).rstrip())
        if n == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def format_notes(figs: dict) -> str:
    """What each figure measures and against what (one line each)."""
    return "\n".join(f"- {k}: {f['note']}" for k, f in figs.items() if f.get("note"))


def format_targets(figs: dict) -> str:
    """One line per figure with a target: met, or by how much not (value over target, or
    target over value where higher is better), with the same run's baseline."""
    lines = []
    for k, f in figs.items():
        if f.get("met") is None:
            continue
        v, t, b = f["value"], f["target"], f["baseline"]
        over = max(v / t, t / v) if v and t else None
        verdict = "met" if f["met"] else ("NOT met" + (f", {over:.2f}x off" if over else ""))
        base = f" (baseline in this run {fmt(b)} {f['unit']})" if b is not None else ""
        lines.append(f"- {k}: {fmt(v)} {f['unit']} against {fmt(t)}: {verdict}{base}")
    return "\n".join(lines)


def standalone(run: Callable[[bool], dict], doc: str, quick_help: str = "shorter version") -> None:
    """Parse ``--quick`` and ``--json FILE``, run the section, print its table and notes."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help=quick_help)
    ap.add_argument("--json", metavar="FILE", default=None, help="also write the figures as JSON")
    args = ap.parse_args()
    figs = run(args.quick)
    print(format_table(figs))
    print()
    print(format_notes(figs))
    targets = format_targets(figs)
    if targets:
        print("\ntargets:\n" + targets)
    if args.json:
        Path(args.json).write_text(json.dumps(figs, indent=1))
