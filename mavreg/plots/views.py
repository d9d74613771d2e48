"""Map-correct views of a path: a 3-D view, a top view and a side view, at equal scale.

Every view is drawn as a map is read: east to the right, north up in the top view,
altitude (up positive) up in the side and 3-D views. The side view looks along the
horizontal axis the path spans least, so a loop in the east-down plane is seen face on.
Segment starts are numbered along the path (the key is in the figure's title); the start,
the end and the direction of travel are marked.
"""
from __future__ import annotations

import textwrap

import numpy as np

__all__ = ["ViewLine", "draw_views", "to_map", "SIDE_AXES", "views_height_in"]

MIN_ASPECT = 0.3
"""A view's shorter side is at least this fraction of its longer (a flat path's side view
keeps a readable band of altitude around it)."""

SIDE_AXES = {"east": ("east (m)", "side view from the south", 0),
             "north": ("north (m)", "side view from the east", 1)}
"""Side view's horizontal axis: (label, title, column of the map coordinates)."""


class ViewLine:
    """One curve in every view: NED positions and a matplotlib style."""

    def __init__(self, ned, label: str | None, **style):
        self.ned = np.asarray(ned, dtype=float).reshape(-1, 3)
        self.label = label
        self.style = style


def to_map(ned) -> np.ndarray:
    """(east, north, altitude) columns of NED positions: the views' x, y and z."""
    p = np.asarray(ned, dtype=float).reshape(-1, 3)
    return np.column_stack([p[:, 1], p[:, 0], -p[:, 2]])


def _limits(lo, hi, pad: float = 0.08):
    """Equal-scale limits around [lo, hi] (per axis), each at least MIN_ASPECT of the longest."""
    span = np.maximum(hi - lo, 1e-9)
    longest = float(span.max())
    half = 0.5 * np.maximum(span, MIN_ASPECT * longest) * (1 + 2 * pad)
    mid = 0.5 * (lo + hi)
    return mid - half, mid + half


def _set_equal_2d(ax, lo, hi) -> None:
    a, b = _limits(np.asarray(lo), np.asarray(hi))
    ax.set_xlim(a[0], b[0])
    ax.set_ylim(a[1], b[1])
    ax.set_box_aspect((b[1] - a[1]) / (b[0] - a[0]))   # equal scale: the box has the data's shape
    ax.grid(color="0.9", lw=0.6)


def views_height_in(reference_ned, others=(), cell_width_in: float = 3.2) -> float:
    """Height (inches) of the views' row: enough for the taller of the top and side views at
    equal scale in a cell ``cell_width_in`` wide, between 3.8 (the key fits) and 5.4 inches."""
    pts = np.vstack([to_map(reference_ned)] + [to_map(o) for o in others if len(o)])
    span = np.maximum(np.nanmax(pts, axis=0) - np.nanmin(pts, axis=0), 1e-9)
    h = 0 if side_axis(reference_ned) == "east" else 1
    aspects = []
    for x, y in ((span[0], span[1]), (span[h], span[2])):
        longest = max(x, y)
        aspects.append(max(y, MIN_ASPECT * longest) / max(x, MIN_ASPECT * longest))
    return float(np.clip(cell_width_in * max(aspects) + 1.0, 3.8, 5.4))


def side_axis(reference_ned) -> str:
    """'east' or 'north': the horizontal axis of the side view (the longer horizontal span)."""
    m = to_map(reference_ned)
    return "east" if np.ptp(m[:, 0]) >= np.ptp(m[:, 1]) else "north"


def draw_views(fig, cells, reference_ned, segment_starts_ned, segment_names, lines, marks=()):
    """Draw the 3-D, top and side views and their key into four gridspec ``cells``.

    Parameters
    ----------
    reference_ned : (N, 3) the nominal path, in order of s (start, end and direction from it).
    segment_starts_ned : (K, 3) the first point of each segment, numbered 1..K.
    segment_names : (K,) their names, listed in the key.
    lines : list of :class:`ViewLine`, drawn over the nominal.
    marks : iterable of (ned (3,), text, style dict): single points (a failure).

    Returns
    -------
    (ax3d, ax_top, ax_side, ax_key)
    """
    ref = to_map(reference_ned)
    every = [to_map(ln.ned) for ln in lines if ln.ned.size] + [ref]
    lo = np.min([np.nanmin(m, axis=0) for m in every], axis=0)
    hi = np.max([np.nanmax(m, axis=0) for m in every], axis=0)
    ax3 = fig.add_subplot(cells[0], projection="3d")
    top = fig.add_subplot(cells[1])
    side = fig.add_subplot(cells[2])
    key = fig.add_subplot(cells[3])
    for ax, name in ((ax3, "3d"), (top, "top"), (side, "side"), (key, "key")):
        ax.set_label(name)                 # how tests and tools find a panel
    h_name = side_axis(reference_ned)
    h_label, side_title, h_col = SIDE_AXES[h_name]
    cols = {top: (0, 1), side: (h_col, 2)}
    for ax, (i, j) in cols.items():
        ax.plot(ref[:, i], ref[:, j], color="0.35", ls="--", lw=1.0, label="nominal path", zorder=2)
        for ln in lines:
            m = to_map(ln.ned)
            ax.plot(m[:, i], m[:, j], label=ln.label, zorder=3, **ln.style)
        _set_equal_2d(ax, lo[[i, j]], hi[[i, j]])
        _arrows(ax, ref[:, [i, j]])
        _ends(ax, ref[:, [i, j]])
        _number_segments(ax, to_map(segment_starts_ned)[:, [i, j]])
        for ned, text, style in marks:
            p = to_map(ned)[0]
            ax.plot(p[i], p[j], ls="none", zorder=6, **style, label=text)
    top.set_xlabel("east (m)")
    top.set_ylabel("north (m)")
    top.set_title("top view (north up)", fontsize=9)
    side.set_xlabel(h_label)
    side.set_ylabel("altitude (m)")
    side.set_title(side_title, fontsize=9)
    _draw_3d(ax3, ref, lines, lo, hi, marks)
    _key(key, top, segment_names)
    return ax3, top, side, key


def _draw_3d(ax, ref, lines, lo, hi, marks) -> None:
    ax.plot(ref[:, 0], ref[:, 1], ref[:, 2], color="0.35", ls="--", lw=1.0)
    for ln in lines:
        m = to_map(ln.ned)
        ax.plot(m[:, 0], m[:, 1], m[:, 2], **ln.style)
    ax.scatter(*ref[0], color="tab:green", s=30, depthshade=False)
    ax.scatter(*ref[-1], color="k", marker="s", s=22, depthshade=False)
    k = max(1, len(ref) // 6)
    for a in range(k // 2, len(ref) - 1, k):
        d = ref[min(a + max(1, len(ref) // 200), len(ref) - 1)] - ref[a]
        n = np.linalg.norm(d)
        if n > 0:
            L = 0.06 * float(np.max(hi - lo))
            ax.quiver(*ref[a], *(d / n * L), color="0.2", arrow_length_ratio=0.6, lw=1.2)
    for ned, _, style in marks:
        p = to_map(ned)[0]
        ax.scatter(*p, color=style.get("color", "r"), marker=style.get("marker", "X"), s=60,
                   depthshade=False, zorder=6)
    a, b = _limits(lo, hi, pad=0.02)
    ax.set_xlim(a[0], b[0])
    ax.set_ylim(a[1], b[1])
    ax.set_zlim(a[2], b[2])
    ax.set_box_aspect(tuple(b - a), zoom=0.82)         # equal scale; the labels stay in its cell
    ax.set_xlabel("east (m)", labelpad=0, fontsize=8)
    ax.set_ylabel("north (m)", labelpad=0, fontsize=8)
    ax.set_zlabel("altitude (m)", labelpad=0, fontsize=8)
    ax.tick_params(labelsize=7, pad=0)
    from matplotlib.ticker import MaxNLocator
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(4))
        axis.set_pane_color((1.0, 1.0, 1.0, 0.0))     # white panes: the grid alone gives depth
    ax.set_title("3-D view (altitude up)", fontsize=9)


def _arrows(ax, xy, count: int = 5) -> None:
    """Arrow heads along the path, in the direction of travel."""
    n = len(xy)
    span = np.ptp(np.concatenate([ax.get_xlim(), ax.get_ylim()]))
    step = max(1, n // 400)
    for a in np.linspace(0.1, 0.9, count):
        i = int(a * (n - 1))
        j = min(i + step, n - 1)
        d = xy[j] - xy[i]
        if np.linalg.norm(d) < 1e-9 * span:
            continue              # seen end on (a path crossing the view's line of sight)
        d = d / np.linalg.norm(d) * 0.03 * span
        ax.annotate("", xy=xy[i] + d, xytext=xy[i], zorder=5,
                    arrowprops=dict(arrowstyle="-|>", color="0.15", lw=1.2, mutation_scale=11))


def _ends(ax, xy) -> None:
    ax.plot(*xy[0], "o", color="tab:green", ms=7, zorder=7, label="start")
    ax.plot(*xy[-1], "s", color="k", ms=5, zorder=7, label="end")


_OFFSETS = [(0.035, 0.035), (0.035, -0.07), (-0.07, 0.035), (-0.07, -0.07), (0.0, 0.08),
            (0.0, -0.11), (0.08, 0.0), (-0.11, 0.0), (0.08, 0.09), (-0.11, 0.09), (0.08, -0.12),
            (-0.11, -0.12)]
_LABEL_W, _LABEL_H = 0.045, 0.06      # a number's box, as a fraction of the axes (approx.)


def _number_segments(ax, starts_xy) -> None:
    """Number each segment at its first point, moving a number off the others it would cover."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    placed = []
    for k, (x, y) in enumerate(starts_xy, start=1):
        fx, fy = (x - x0) / (x1 - x0), (y - y0) / (y1 - y0)
        choice = _OFFSETS[-1]
        for dx, dy in _OFFSETS:
            box = (fx + dx, fy + dy)
            inside = 0 <= box[0] <= 1 - _LABEL_W and 0 <= box[1] <= 1 - _LABEL_H
            if inside and all(abs(box[0] - b[0]) > _LABEL_W or abs(box[1] - b[1]) > _LABEL_H
                              for b in placed):
                choice = (dx, dy)
                break
        placed.append((fx + choice[0], fy + choice[1]))
        ax.plot(x, y, marker="|" if k > 1 else "None", color="tab:purple", ms=9, mew=1.5, zorder=6)
        ax.annotate(str(k), xy=(x, y), xytext=(fx + choice[0], fy + choice[1]), textcoords="axes fraction",
                    fontsize=7, color="tab:purple", zorder=8, annotation_clip=False,
                    bbox=dict(boxstyle="circle,pad=0.15", fc="white", ec="tab:purple", lw=0.6),
                    arrowprops=dict(arrowstyle="-", color="tab:purple", lw=0.5, shrinkA=0, shrinkB=2))


def _key(ax, source, segment_names) -> None:
    """The views' legend and the segment numbers, in a panel of their own (no view is covered)."""
    ax.set_axis_off()
    handles, labels = source.get_legend_handles_labels()
    seen = {}
    for h, lab in zip(handles, labels):
        if lab and not lab.startswith("_") and lab not in seen:
            seen[lab] = h
    leg = ax.legend(seen.values(), [textwrap.fill(lab, 18) for lab in seen], loc="upper left", fontsize=7,
                    frameon=False, borderaxespad=0.0)
    ax.add_artist(leg)
    text = "segments (numbered\nalong the path):\n" + "\n".join(
        f"{k:<3}" + name.replace(">", ">\n   ") for k, name in enumerate(segment_names, start=1))
    ax.text(0.0, 0.0, text, transform=ax.transAxes, fontsize=7, va="bottom", ha="left",
            color="tab:purple", family="monospace")
