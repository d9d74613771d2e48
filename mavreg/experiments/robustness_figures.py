"""The robustness experiment's figures: every flight of every cell, by outcome.

``robustness_cells.png``: a row per cell (matrix order, top to bottom), two panels sharing
the rows: the largest distance from the path over the maneuver (log scale; a flight whose
maneuver never started is not drawn there), and the lowest altitude after the take-off
(0: the ground touched). Each flight is a dot, jittered within its row, coloured by outcome:
ok green, failed but safe orange, unsafe red (a cross); the loop's largest error is a small
open circle beside it where the maneuver has a loop.

``robustness_mismatch.png`` (when the mismatch cell flew): the same error against each drawn
airframe parameter (mass, the largest inertia change, the spread of the rotors' thrust
constants, yaw coefficient, motor lag, centre-of-mass offset), one panel each: which draws
the failures share.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .figures import _plt

__all__ = ["robustness_figures", "OUTCOME_STYLE"]

OUTCOME_STYLE = {
    "ok": dict(color="tab:green", marker="o", s=16, label="ok"),
    "failed, safe": dict(color="tab:orange", marker="o", s=20, label="failed, safe"),
    "unsafe": dict(color="tab:red", marker="X", s=36, label="unsafe"),
    "failed": dict(color="tab:red", marker="o", s=20, label="failed"),          # via sim: diverged, timed out
    "not flown": dict(color="0.4", marker="s", s=14, label="not flown"),
}
_DPI = 85
_FLOOR_M = 1e-3
"""Errors under 1 mm are drawn at 1 mm (log axis)."""


def _jitter(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(-0.25, 0.25, n) if n > 1 else np.zeros(n)


def robustness_figures(out_dir: Path, outcomes, cells) -> list[Path]:
    """Draw ``robustness_cells.png`` into ``out_dir``; its path in a list."""
    from .robustness_report import flight_rows
    plt = _plt()
    rows = flight_rows(outcomes)
    names = [c.name for c in cells if any(m.get("cell") == c.name for m in rows)]
    if not names:
        return []
    y_of = {n: len(names) - 1 - i for i, n in enumerate(names)}
    height_in = 2.0 + 0.28 * len(names)
    fig, (ax_e, ax_h) = plt.subplots(1, 2, figsize=(11, height_in), sharey=True,
                                     gridspec_kw={"width_ratios": (3, 2)})
    drawn = set()
    for k, name in enumerate(names):
        mine = [m for m in rows if m.get("cell") == name]
        y = y_of[name] + _jitter(len(mine), k)
        for m, yy in zip(mine, y):
            st = dict(OUTCOME_STYLE[m["safety"]])
            label = st.pop("label")
            lab = label if label not in drawn else None
            drawn.add(label)
            if m.get("maneuver_max_error_m") is not None:
                ax_e.scatter(max(m["maneuver_max_error_m"], _FLOOR_M), yy, label=lab, zorder=3, **st)
            if m.get("loop_max_error_m") is not None:
                ax_e.scatter(max(m["loop_max_error_m"], _FLOOR_M), yy, s=14, facecolors="none",
                             edgecolors=st["color"], linewidths=0.7, zorder=2)
            if m.get("lowest_altitude_m") is not None:
                ax_h.scatter(m["lowest_altitude_m"], yy, zorder=3, **st)
    from matplotlib.ticker import NullFormatter
    ax_e.set_xscale("log")
    top = max([m["maneuver_max_error_m"] for m in rows if m.get("maneuver_max_error_m") is not None], default=1.0)
    ax_e.set_xlim(_FLOOR_M * 0.7, max(2.0, 1.5 * top))
    ax_e.xaxis.set_minor_formatter(NullFormatter())
    lows = [m["lowest_altitude_m"] for m in rows if m.get("lowest_altitude_m") is not None]
    ax_h.set_xlim(-0.2, max(3.5, max(lows, default=0.0) + 0.3))
    if not lows:                                   # via sim: the maneuver alone, no take-off
        ax_h.text(0.5, 0.5, "via sitl only", transform=ax_h.transAxes, ha="center", color="0.4")
    ax_e.axvline(0.5, color="0.5", ls="--", lw=0.8)
    ax_e.set_xlabel("largest distance from the path, maneuver (m; open: loop; dashed: envelope 0.5 m)",
                    fontsize=8)
    ax_h.axvline(1.0, color="0.5", ls="--", lw=0.8)
    ax_h.set_xlabel("lowest altitude after take-off (m; dashed: 1 m floor)", fontsize=8)
    ax_e.set_yticks(range(len(names)))
    ax_e.set_yticklabels(list(reversed(names)), fontsize=8)
    ax_e.set_ylim(-0.6, len(names) - 0.4)
    for ax in (ax_e, ax_h):
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    handles, labels = ax_e.get_legend_handles_labels()
    if labels:
        fig.legend(handles, labels, loc="lower center", fontsize=8, ncol=len(labels))
    fig.suptitle("Robustness: every flight of every cell", fontsize=11)
    fig.tight_layout(rect=(0, 0.35 / height_in if labels else 0.0, 1, 1 - 0.3 / height_in))
    path = Path(out_dir) / "robustness_cells.png"
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return [path, *_mismatch_figure(plt, out_dir, rows)]


MISMATCH_AXES = (
    ("mass (%)", lambda d: 100 * d["mass_rel"]),
    ("largest inertia change (%)", lambda d: 100 * max(d["inertia_rel"], key=abs)),
    ("rotor thrust spread, max - min (%)", lambda d: 100 * (max(d["rotor_gain_rel"]) - min(d["rotor_gain_rel"]))),
    ("yaw coefficient (%)", lambda d: 100 * d["drag_torque_ratio_rel"]),
    ("motor lag (ms)", lambda d: 1e3 * d["rotor_time_constant_s"]),
    ("centre-of-mass offset (mm)", lambda d: 1e3 * float(np.hypot(*d["com_offset_m"][:2]))),
)
"""Each panel's x: a number from the emulator's drawn airframe (``airframe.mismatch`` of the record)."""


def _drawn(m) -> dict | None:
    return ((m.get("airframe") or {}).get("mismatch")) if m.get("cell") == "mismatch" else None


def _mismatch_figure(plt, out_dir, rows) -> list[Path]:
    from matplotlib.ticker import NullFormatter
    mine = [m for m in rows if _drawn(m) and m.get("maneuver_max_error_m") is not None]
    if not mine:
        return []
    fig, axes = plt.subplots(2, 3, figsize=(11, 6), sharey=True)
    drawn = set()
    for ax, (name, of) in zip(axes.ravel(), MISMATCH_AXES):
        for m in mine:
            st = dict(OUTCOME_STYLE[m["safety"]])
            label = st.pop("label")
            try:
                x = of(_drawn(m))
            except (KeyError, TypeError, ValueError):  # a record without that field
                continue
            ax.scatter(x, max(m["maneuver_max_error_m"], _FLOOR_M), label=None if label in drawn else label,
                       zorder=3, **st)
            drawn.add(label)
        ax.set_xlabel(name, fontsize=8)
        ax.set_yscale("log")
        ax.yaxis.set_minor_formatter(NullFormatter())
        ax.axhline(0.5, color="0.5", ls="--", lw=0.8)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=8)
    for ax in axes[:, 0]:
        ax.set_ylabel("largest distance from the path (m)", fontsize=8)
    found = {}
    for ax in axes.ravel():
        found.update(zip(*reversed(ax.get_legend_handles_labels())))
    labels = [st["label"] for st in OUTCOME_STYLE.values() if st["label"] in found]
    handles = [found[lab] for lab in labels]
    if labels:
        fig.legend(handles, labels, loc="lower center", fontsize=8, ncol=len(labels))
    fig.suptitle(f"Drawn airframes ({len(mine)} flights): maneuver error against each drawn parameter", fontsize=11)
    fig.tight_layout(rect=(0, 0.05 if labels else 0.0, 1, 0.96))
    path = Path(out_dir) / "robustness_mismatch.png"
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)
    return [path]
