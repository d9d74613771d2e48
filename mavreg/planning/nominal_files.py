"""The plan's nominal table in files: ``mavreg plan --export FILE.csv|json`` and back.

The table is :func:`mavreg.maneuver.nominal_table.nominal_table` (one row per node of the
plan's grid, every column named with its unit); here it is written as CSV (one header line
of unit-named columns) or JSON (one object, one array per quantity), and a CSV read back.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import UsageError
from ..maneuver.nominal_table import COLUMN_GROUPS, CSV_COLUMNS, nominal_table

__all__ = ["write_nominal", "read_nominal_csv", "check_export_path", "EXPORT_SUFFIXES"]

EXPORT_SUFFIXES = (".csv", ".json")


def check_export_path(path) -> Path:
    """The export file's path, or a one-line ``UsageError`` for a suffix it cannot write."""
    path = Path(path)
    if path.suffix.lower() not in EXPORT_SUFFIXES:
        raise UsageError(f"--export {path}: the file name must end in .csv or .json")
    return path


def write_nominal(plan, path) -> Path:
    """Write the nominal table as CSV (a header of unit-named columns) or JSON (by suffix)."""
    path = check_export_path(path)
    table = nominal_table(plan)
    if path.suffix.lower() == ".csv":
        cols = np.column_stack([np.asarray(table[k], dtype=float).reshape(len(plan.s), -1)
                                for k, _ in COLUMN_GROUPS])
        with open(path, "w", encoding="utf-8", newline="") as fh:
            fh.write(",".join(CSV_COLUMNS) + "\n")
            np.savetxt(fh, cols, delimiter=",", fmt="%.12g")
    else:
        doc = {"maneuver": plan.name, "length_m": plan.length_m, "duration_s": plan.duration_s,
               "frame": "NED (north, east, down); body FRD; quaternion wxyz, body to NED; "
                        "rotors 1-4 front, right, back, left",
               "segments": [{"name": n, "s_start_m": a, "s_end_m": b} for n, a, b in plan.segments],
               "rows": int(len(plan.s)),
               **{k: np.asarray(v, dtype=float).tolist() for k, v in table.items()}}
        path.write_text(json.dumps(doc, separators=(",", ":")), encoding="utf-8")
    return path


def read_nominal_csv(path) -> dict[str, np.ndarray]:
    """A CSV written by :func:`write_nominal`, back as the JSON-keyed table."""
    with open(path, encoding="utf-8") as fh:
        header = fh.readline().strip().split(",")
        data = np.loadtxt(fh, delimiter=",", ndmin=2)
    col = {name: data[:, i] for i, name in enumerate(header)}
    out = {}
    for key, names in COLUMN_GROUPS:
        block = np.column_stack([col[n] for n in names])
        out[key] = block[:, 0] if len(names) == 1 else block
    return out
