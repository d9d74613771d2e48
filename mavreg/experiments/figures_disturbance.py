"""The gust and lag experiments' figures: the three controllers side by side, case by case.

One set of figures per group of runs (gust: where it strikes; lag: all of it), each a grid
with a row per case (the force, or the reference's lead) and a column per rotor limit:

- ``NAME_GROUP_paths.png``: the paths in the plane of the loop (east against altitude),
  zoomed on where any run is more than 2 cm off the path, with the loop;
- ``NAME_GROUP_distance.png``: the distance from the path against time, the 0.5 m tube
  dashed, the gust's window shaded; a panel with a run lost (more than 2 m off) stops at
  2 m and names its largest distance;
- ``NAME_GROUP_speed.png``: the speed along the path minus the profile's at the vehicle's own
  arc length against time (above zero: faster than the maneuver prescribes where the vehicle
  is; below -v(s): going backwards).

Colours: desired black, maneuver regulation blue, the TVLQR red, the SE(3) tracker green.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .definitions import REGULATOR, SE3, TVLQR, rotors_label
from ..model.rotation import rpy_to_matrix
from .disturbance_metrics import TUBE_M, along_track_speed
from .figures import _plt, nominal_curves, save_with_legend_below

__all__ = ["disturbance_figures", "CONTROLLER_STYLE"]

CONTROLLER_STYLE = {
    REGULATOR: dict(color="tab:blue", lw=1.3, label="maneuver regulation", zorder=4),
    TVLQR: dict(color="tab:red", lw=1.0, label="TVLQR (time-indexed)", zorder=3),
    SE3: dict(color="tab:green", lw=1.0, label="SE(3) tracker (time-indexed)", zorder=3),
}
_DPI = 80
_OFF_PATH_M = 0.02
_FOCUS_MAX_M = 2.0
_SHOWN_S = 7.0
"""The time figures show 7 s from 1 s before the gust (from the start without a gust): every
run is back on its path or its reference by then, or has gone for good."""


def _grid(outcomes):
    """groups -> (cases, rotor limits, {(case, limit): [outcomes]}), in run order."""
    groups: dict = {}
    for o in outcomes:
        sp = o.spec
        cases, limits, cells = groups.setdefault(sp.group, ([], [], {}))
        if sp.case not in cases:
            cases.append(sp.case)
        if sp.saturation_n not in limits:
            limits.append(sp.saturation_n)
        cells.setdefault((sp.case, sp.saturation_n), []).append(o)
    return groups


def _window(ax, outs) -> None:
    w = next((o.spec.gust_window_s for o in outs if o.spec.gust_window_s), None)
    if w is not None:
        ax.axvspan(*w, color="0.9", zorder=0)


def _focus(plan, cells) -> tuple[tuple[float, float], tuple[float, float]]:
    """East and altitude limits: the loop, where the gust blows, and every stretch 2 cm to 2 m
    off the path (a run that leaves for good is drawn as it leaves, not followed)."""
    name = plan.laps_segment or "loop"
    pts = [np.concatenate([plan.path.evaluate(np.linspace(a, b, 200))[0] for n, a, b in plan.segments
                           if n == name])]
    for outs in cells.values():
        for o in outs:
            tr = o.trace
            if tr is not None and tr.t_s.size:
                e = tr.transverse_error_m
                keep = (e > _OFF_PATH_M) & (e < _FOCUS_MAX_M)
                if o.spec.gust_window_s is not None:
                    keep |= (tr.t_s >= o.spec.gust_window_s[0]) & (tr.t_s <= o.spec.gust_window_s[1])
                pts.append(tr.position_m[keep])
    p = np.concatenate(pts)
    e, z = p[:, 1], -p[:, 2]
    return (e.min() - 1.0, e.max() + 1.0), (z.min() - 0.7, z.max() + 0.7)


def _figure(plt, cases, limits, panel_size):
    """A grid of a row per case and a column per rotor limit, at least 8 in wide (the title)."""
    fig, axes = plt.subplots(len(cases), len(limits), figsize=(max(panel_size[0] * len(limits), 8.0),
                                                               panel_size[1] * len(cases)),
                             squeeze=False)
    return fig, axes


def _finish(plt, fig, axes, path: Path, title: str) -> None:
    save_with_legend_below(plt, fig, axes[0, 0], path, title, dpi=_DPI, legend_room=0.04)


def _paths(path: Path, plan, name: str, group: str, cases, limits, cells, via: str) -> None:
    plt = _plt()
    nominal = nominal_curves(plan, step=5)
    xlim, ylim = _focus(plan, cells)
    aspect = (xlim[1] - xlim[0]) / (ylim[1] - ylim[0])
    fig, axes = _figure(plt, cases, limits, (min(3.2 * aspect, 9.0), 3.4))
    for i, case in enumerate(cases):
        for j, lim in enumerate(limits):
            ax = axes[i, j]
            ax.plot(nominal["position"][:, 1], -nominal["position"][:, 2], color="k", lw=0.8, label="desired",
                    zorder=2)
            for o in cells.get((case, lim), []):
                if o.trace is None:
                    continue
                p = o.trace.position_m
                st = CONTROLLER_STYLE[o.spec.controller]
                ax.plot(p[:, 1], -p[:, 2], **st)
                w = o.spec.gust_window_s
                if w is not None:
                    k = np.searchsorted(o.trace.t_s, w)
                    k = k[k < len(p)]
                    ax.plot(p[k, 1], -p[k, 2], "o", ms=3, color=st["color"], zorder=5)
            ax.set_xlim(*xlim)
            ax.set_ylim(*ylim)
            ax.set_aspect("equal")
            ax.grid(alpha=0.3)
            ax.set_title(f"{case}, {rotors_label(lim)}", fontsize=9)
            ax.set_xlabel("east (m)", fontsize=8)
            ax.set_ylabel("altitude (m)", fontsize=8)
    gust = " (dots: the gust's start and end)" if name == "gust" else ""
    _finish(plt, fig, axes, path, f"{name} via {via}, {group}: paths in the plane of the loop{gust}")


def _cap_lost(ax, outs) -> None:
    """A run more than 2 m off the path has left it for good (as in the paths' zoom): the axis
    stops at 2 m, so the other runs stay readable, and the panel names the lost run's largest
    distance."""
    lost = [o for o in outs if o.trace is not None and o.trace.transverse_error_m.max() > _FOCUS_MAX_M]
    if not lost:
        return
    ax.set_ylim(-0.05 * _FOCUS_MAX_M, 1.05 * _FOCUS_MAX_M)
    note = "; ".join(f"{CONTROLLER_STYLE[o.spec.controller]['label'].split(' (')[0]} off the scale, "
                     f"{o.trace.transverse_error_m.max():.1f} m at most" for o in lost)
    ax.text(0.98, 0.92, note, transform=ax.transAxes, ha="right", va="top", fontsize=8)


def _against_time(path: Path, plan, name: str, group: str, cases, limits, cells, via: str, what: str) -> None:
    plt = _plt()
    fig, axes = _figure(plt, cases, limits, (6.5, 2.6))
    t0 = min((o.spec.gust_window_s[0] for outs in cells.values() for o in outs if o.spec.gust_window_s),
             default=0.0)
    t0 = max(t0 - 1.0, 0.0)
    t1 = t0 + _SHOWN_S
    for i, case in enumerate(cases):
        for j, lim in enumerate(limits):
            ax = axes[i, j]
            outs = cells.get((case, lim), [])
            _window(ax, outs)
            for o in outs:
                tr = o.trace
                if tr is None:
                    continue
                if what == "distance":
                    y = tr.transverse_error_m
                else:
                    s = np.clip(tr.s_m, plan.s[0], plan.s[-1])
                    R = rpy_to_matrix(*tr.rpy_rad.T).transpose(2, 0, 1)
                    v_ned = np.einsum("kij,kj->ki", R, tr.velocity_body_m_s)
                    y = along_track_speed(plan.path, s, v_ned) - np.interp(s, plan.s, plan.speed_m_s)
                ax.plot(tr.t_s, y, **CONTROLLER_STYLE[o.spec.controller])
            if what == "distance":
                ax.axhline(TUBE_M, color="k", lw=0.7, ls="--")
                ax.set_ylabel("distance from path (m)", fontsize=8)
                _cap_lost(ax, outs)
            else:
                ax.axhline(0.0, color="k", lw=0.6)
                ax.set_ylabel("along-track speed - v(s) (m/s)", fontsize=8)
            ax.set_xlim(t0, t1)
            ax.grid(alpha=0.3)
            ax.set_title(f"{case}, {rotors_label(lim)}", fontsize=9)
            ax.set_xlabel("time from the start (s)", fontsize=8)
    head = ("distance from the path (dashed: the 0.5 m tube)" if what == "distance"
            else "speed along the path above the profile at the vehicle's arc length")
    _finish(plt, fig, axes, path, f"{name} via {via}, {group}: {head}" + ("; grey: the gust" if name == "gust" else ""))


def disturbance_figures(out_dir: Path, plan, name: str, outcomes, via: str) -> list[Path]:
    """Paths, distance and speed figures of a gust or lag campaign, per group; the paths written."""
    out_dir = Path(out_dir)
    written = []
    runs = [o for o in outcomes if o.trace is not None and o.trace.t_s.size]
    for group, (cases, limits, cells) in _grid(runs).items():
        stem = f"{name}_{group}".replace(" ", "_")
        written.append(out_dir / f"{stem}_paths.png")
        _paths(written[-1], plan, name, group, cases, limits, cells, via)
        for what in ("distance", "speed"):
            written.append(out_dir / f"{stem}_{what}.png")
            _against_time(written[-1], plan, name, group, cases, limits, cells, via, what)
    return written
