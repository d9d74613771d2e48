"""Panels against arc length, and the figure's frame (constrained layout, title, saving)."""
from __future__ import annotations

import textwrap

import numpy as np

__all__ = ["clip_spike", "new_figure", "save", "mark_segments", "error_panel", "no_data", "mark_failure_s",
           "title_lines", "ERROR_FLOOR_CM", "ERROR_FLOOR_DEG", "DPI"]

DPI = 100
ERROR_FLOOR_CM = 1e-6
"""Transverse errors are drawn on a log scale down to 10 nm (a zero would have no place)."""
ERROR_FLOOR_DEG = 1e-7


def new_figure(height_in: float, rows_ratio):
    """A 12-inch-wide figure with constrained layout and a 6-column grid of ``rows_ratio`` rows."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(12, height_in), layout="constrained")
    fig.get_layout_engine().set(h_pad=0.06, w_pad=0.06, hspace=0.04, wspace=0.04)
    gs = fig.add_gridspec(len(rows_ratio), 6, height_ratios=rows_ratio)
    return fig, gs


def save(fig, path) -> None:
    """Save at :data:`DPI`; a PNG in a 256-colour palette (a third of the bytes, no visible loss)."""
    import io

    import matplotlib.pyplot as plt
    from PIL import Image
    if str(path).lower().endswith(".png"):
        buf = io.BytesIO()
        fig.savefig(buf, dpi=DPI, format="png")
        buf.seek(0)
        with Image.open(buf) as im:
            small = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MAXCOVERAGE,
                                               dither=Image.Dither.NONE)
            small.save(path, optimize=True)
    else:
        fig.savefig(path, dpi=DPI)
    plt.close(fig)


def title_lines(*lines: str, width: int = 150) -> str:
    """Lines of a figure title, each wrapped to ``width`` characters."""
    return "\n".join(textwrap.fill(ln, width) for ln in lines if ln)


def mark_segments(ax, segments, numbers_on_top: bool = False) -> None:
    """Boundaries as thin lines; with ``numbers_on_top`` the segment numbers above the panel."""
    for _, a, _ in segments[1:]:
        ax.axvline(a, color="0.75", lw=0.6, zorder=1)
    ax.grid(color="0.9", lw=0.6)
    if numbers_on_top:
        top = ax.secondary_xaxis("top")
        top.set_xticks([0.5 * (a + b) for _, a, b in segments],
                       labels=[str(k) for k in range(1, len(segments) + 1)])
        top.tick_params(length=0, labelsize=7, labelcolor="tab:purple", pad=1)


def error_panel(ax, s, values, floor: float, style: dict, label: str | None) -> None:
    """``values`` against ``s`` on a log scale, below-floor values drawn at the floor."""
    v = np.maximum(np.asarray(values, dtype=float), floor)
    ax.plot(s, v, label=label, **style)
    ax.set_yscale("log")


def no_data(ax, text: str) -> None:
    """Say in the panel why it has nothing to draw (instead of leaving it empty)."""
    ax.text(0.5, 0.5, textwrap.fill(text, 60), transform=ax.transAxes, ha="center", va="center",
            fontsize=9, color="0.3", bbox=dict(fc="0.96", ec="0.8", boxstyle="round"))
    ax.set_xticks([])
    ax.set_yticks([])


def mark_failure_s(ax, s_m: float | None, label: str | None = None) -> None:
    """A red line where the flight failed (nothing when it failed off the path: s unknown)."""
    if s_m is not None and np.isfinite(s_m) and ax.has_data():
        ax.axvline(s_m, color="tab:red", lw=1.3, ls="-", zorder=5, label=label)


def clip_spike(ax, s, values, top: float, unit: str) -> None:
    """Keep the y axis to ``top`` when a short transient (a start far off the path) goes
    beyond it: its peak is marked at the top edge and named in the legend, not drawn to scale."""
    v = np.asarray(values, dtype=float).reshape(len(s), -1)
    peak = float(np.nanmax(v)) if v.size else -np.inf
    if not np.isfinite(peak) or peak <= 1.25 * top:    # not far beyond: drawn to scale
        return
    i = int(np.nanargmax(np.nanmax(v, axis=1)))
    lo = ax.get_ylim()[0]
    ax.set_ylim(lo, top)
    ax.plot([s[i]], [top], marker="^", color="tab:red", ms=7, ls="none", clip_on=False, zorder=6,
            label=f"off scale: peak {peak:.1f} {unit} at s = {s[i]:.2f} m")
