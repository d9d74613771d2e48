"""The experiments' figures, after the paper's Figs. 2-7 (matplotlib, Agg backend).

Colours follow the paper: in group 1 the desired maneuver is thick blue, the run on the
nominal inertia thick red, the runs on drawn inertias thin lines; in group 2 the desired
maneuver is black and the cases are blue (no saturation), red (8.5 N) and green (7 N).
Every quantity is drawn against the arc length s of the nearest path point (the truth's).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..model.mixer import Mixer
from ..model.rotation import wrap_angle

__all__ = ["group1_figures", "group2_figures", "nominal_curves", "save_with_legend_below"]

_DESIRED = dict(color="tab:blue", lw=2.2, zorder=3)
_NOMINAL_RUN = dict(color="tab:red", lw=1.6, zorder=4)
_CASE_COLOURS = ("tab:blue", "tab:red", "tab:green", "tab:purple", "tab:orange")
_DPI = 85


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def nominal_curves(plan, step: int = 20) -> dict:
    """The desired maneuver on the plan's grid (every ``step``-th node): s, position, roll
    pitch yaw (deg), body velocity, thrust and torques, rotor forces."""
    s = plan.s[::step]
    x = plan.x[::step]
    u = plan.u[::step]
    mixer = Mixer.from_vehicle(plan.vehicle)
    return {"s": s, "position": x[:, :3], "rpy_deg": np.degrees(x[:, 3:6]), "v_body": x[:, 6:9],
            "u": u, "rotors": u @ mixer.inverse.T}


def _segments(ax, plan) -> None:
    """Shade the laps segment, mark where the run-up ends."""
    name = plan.laps_segment or "loop"
    for n, a, b in plan.segments:
        if n == name:
            ax.axvspan(a, b, color="0.93", zorder=0)
    ax.axvline(plan.segments[0][2], color="0.6", lw=0.6, ls=":", zorder=1)
    ax.grid(alpha=0.3)


def _thin_colours(n: int):
    import matplotlib
    cmap = matplotlib.colormaps["viridis"]
    return [cmap(0.1 + 0.8 * i / max(n - 1, 1)) for i in range(n)]


def _runs(outcomes):
    return [o for o in outcomes if o.trace is not None and o.trace.t_s.size]


def _style_group1(outcomes):
    """(outcome, style) with the nominal-inertia run last (drawn on top)."""
    rest = [o for o in outcomes if o.spec.inertia_kg_m2 is not None]
    cols = _thin_colours(len(rest))
    out = [(o, dict(color=c, lw=0.6, alpha=0.8, zorder=2)) for o, c in zip(rest, cols)]
    out += [(o, _NOMINAL_RUN) for o in outcomes if o.spec.inertia_kg_m2 is None]
    return out


def _style_group2(outcomes):
    return [(o, dict(color=_CASE_COLOURS[i % len(_CASE_COLOURS)], lw=0.9, zorder=3, label=o.spec.label))
            for i, o in enumerate(outcomes)]


def _plane(ax, nominal, styled, desired) -> None:
    """p2 (east) against altitude (-p3), the plane of the barrel roll."""
    ax.plot(nominal["position"][:, 1], -nominal["position"][:, 2], label="desired", **desired)
    for o, st in styled:
        p = o.trace.position_m
        ax.plot(p[:, 1], -p[:, 2], **st)
    ax.set_aspect("equal")
    ax.set_xlabel("p2 = east (m)")
    ax.set_ylabel("-p3 = altitude (m)")
    ax.grid(alpha=0.3)


def _deviations(plan, tr) -> tuple[np.ndarray, np.ndarray]:
    """Roll minus the desired roll at the same s (deg, wrapped) and speed minus the profile's."""
    s = np.clip(tr.s_m, plan.s[0], plan.s[-1])
    droll = tr.rpy_rad[:, 0] - np.interp(s, plan.s, plan.x[:, 3])
    droll = np.degrees(wrap_angle(droll))
    dv = np.linalg.norm(tr.velocity_body_m_s, axis=1) - np.interp(s, plan.s, plan.speed_m_s)
    return droll, dv


def _attitude_velocity(path: Path, plan, nominal, styled, desired, title: str, xlim=None) -> None:
    """Fig. 3 / 7: roll, pitch, yaw and body velocities against s; a last row shows what a
    0-1000 deg roll axis hides: the roll's and the speed's deviations at the same s."""
    plt = _plt()
    fig, axes = plt.subplots(4, 2, figsize=(11, 10.5), sharex=True)
    names = (("roll (deg)", "v_x body (m/s)"), ("pitch (deg)", "v_y body (m/s)"), ("yaw (deg)", "v_z body (m/s)"))
    a, b = axes[3]
    for o, st in styled:
        droll, dv = _deviations(plan, o.trace)
        a.plot(o.trace.s_m, droll, **st)
        b.plot(o.trace.s_m, dv, **st)
    a.set_ylabel("roll - desired (deg)")
    b.set_ylabel("speed - profile (m/s)")
    _segments(a, plan)
    _segments(b, plan)
    for i in range(3):
        a, b = axes[i]
        a.plot(nominal["s"], nominal["rpy_deg"][:, i], **desired)
        b.plot(nominal["s"], nominal["v_body"][:, i], **desired)
        for o, st in styled:
            tr = o.trace
            a.plot(tr.s_m, np.degrees(tr.rpy_rad[:, i]), **st)
            b.plot(tr.s_m, tr.velocity_body_m_s[:, i], **st)
        a.set_ylabel(names[i][0])
        b.set_ylabel(names[i][1])
        _segments(a, plan)
        _segments(b, plan)
    for ax in axes[-1]:
        ax.set_xlabel("arc length s (m)")
    if xlim is not None:
        _zoom(axes.ravel(), xlim)
    save_with_legend_below(plt, fig, axes[0, 0], path, title)


def save_with_legend_below(plt, fig, ax, path: Path, title: str, dpi: int = _DPI, legend_room: float = 0.03) -> None:
    """``ax``'s legend centred below the panels (if it has one), the title above; save, close."""
    handles, labels = ax.get_legend_handles_labels()
    if labels:
        fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0.0, legend_room if labels else 0.0, 1.0, 1.0))
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def _zoom(axes, xlim) -> None:
    """Show ``xlim`` of s, each y axis fitted to the lines within it."""
    for ax in axes:
        ax.set_xlim(*xlim)
        lo, hi = np.inf, -np.inf
        for line in ax.get_lines():
            x, y = (np.asarray(v, dtype=float) for v in line.get_data())
            if line.get_transform() is not ax.transData or x.size != y.size:
                continue                       # axvline and the like
            y = y[(x >= xlim[0]) & (x <= xlim[1])]
            if y.size:
                lo, hi = min(lo, y.min()), max(hi, y.max())
        if np.isfinite(lo):
            pad = 0.05 * (hi - lo) + 1e-6
            ax.set_ylim(lo - pad, hi + pad)


def _errors(path: Path, plan, styled, title: str, threshold_m: float | None) -> None:
    plt = _plt()
    fig, (a, b) = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
    for o, st in styled:
        tr = o.trace
        a.plot(tr.s_m, 100 * np.maximum(tr.transverse_error_m, 1e-5), **st)
        b.plot(tr.s_m, tr.attitude_error_deg, **st)
    a.set_yscale("log")
    a.set_ylabel("transverse error (cm)")
    b.set_ylabel("attitude error (deg)")
    b.set_xlabel("arc length s (m)")
    if threshold_m is not None:
        a.axhline(100 * threshold_m, color="k", lw=0.8, ls="--", label=f"{100 * threshold_m:g} cm")
    for ax in (a, b):
        _segments(ax, plan)
    handles, labels = a.get_legend_handles_labels()
    if labels:
        a.legend(fontsize=8, loc="upper right")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)


def group1_figures(out_dir: Path, plan, outcomes, via: str, nominal_inertia) -> list[Path]:
    """Figs. 2, 3, 4 of the paper and the errors, for a convergence experiment; the paths written."""
    plt = _plt()
    out_dir = Path(out_dir)
    nominal = nominal_curves(plan)
    runs = _runs(outcomes)
    styled = _style_group1(runs)
    written = []
    # Fig. 2: inertia samples, paths in 3-D and in the p2-p3 plane
    fig = plt.figure(figsize=(13, 9.5))
    grid = fig.add_gridspec(2, 2, height_ratios=(1.0, 0.8))
    a = fig.add_subplot(grid[0, 0])
    J0 = np.asarray(nominal_inertia, dtype=float)
    drawn = [(o.spec.index, o.spec.inertia_kg_m2) for o in outcomes if o.spec.inertia_kg_m2 is not None]
    for k, (name, col, mk) in enumerate((("jx", "tab:blue", "o"), ("jy", "tab:red", "s"), ("jz", "tab:green", "^"))):
        if drawn:
            a.plot([i for i, _ in drawn], [J[k] for _, J in drawn], mk, color=col, ms=4, label=name)
        a.axhline(J0[k], color=col, lw=0.8)
    a.set_xlabel("sample")
    a.set_ylabel("moment of inertia (kg m²)")
    a.set_title("(a) inertia samples (lines: nominal)", fontsize=10)
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
    b = fig.add_subplot(grid[0, 1], projection="3d")
    P = nominal["position"]
    b.plot(P[:, 0], P[:, 1], -P[:, 2], **{k: v for k, v in _DESIRED.items() if k != "zorder"})
    for o, st in styled:
        p = o.trace.position_m
        b.plot(p[:, 0], p[:, 1], -p[:, 2], **{k: v for k, v in st.items() if k != "zorder"})
    b.set_xlabel("p1 = north (m)")
    b.set_ylabel("p2 = east (m)")
    b.set_zlabel("altitude (m)")
    b.set_title("(b) paths", fontsize=10)
    c = fig.add_subplot(grid[1, :])
    _plane(c, nominal, styled, _DESIRED)
    c.set_title("(c) paths in the p2-p3 plane", fontsize=10)
    fig.suptitle(f"paper-group1 via {via}: 0.6 m off in each axis, {len(drawn)} drawn inertias "
                 "(blue: desired, red: nominal inertia)", fontsize=11)
    fig.tight_layout()
    written.append(out_dir / "fig2_inertia_paths.png")
    fig.savefig(written[-1], dpi=_DPI)
    plt.close(fig)
    # Fig. 3: attitude and body velocities against s
    written.append(out_dir / "fig3_attitude_velocity.png")
    _attitude_velocity(written[-1], plan, nominal, styled, _DESIRED,
                       f"paper-group1 via {via}: attitude and body velocity (blue: desired, red: nominal inertia)")
    s0 = min(float(o.trace.s_m.min()) for o, _ in styled) if styled else 0.0
    written.append(out_dir / "fig3_start.png")
    _attitude_velocity(written[-1], plan, nominal, styled, _DESIRED,
                       f"paper-group1 via {via}: the start, where the runs converge", xlim=(s0 - 0.1, 2.0))
    # Fig. 4: thrust and torques
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    names = ("thrust f (N)", "torque γ1 (N m)", "torque γ2 (N m)", "torque γ3 (N m)")
    for i, ax in enumerate(axes.ravel()):
        ax.plot(nominal["s"], nominal["u"][:, i], **_DESIRED)
        for o, st in styled:
            ax.plot(o.trace.s_m, o.trace.wrench_command[:, i], **st)
        ax.set_ylabel(names[i])
        _segments(ax, plan)
    for ax in axes[-1]:
        ax.set_xlabel("arc length s (m)")
    fig.suptitle(f"paper-group1 via {via}: commanded thrust and torques (blue: desired, red: nominal inertia)",
                 fontsize=11)
    fig.tight_layout()
    written.append(out_dir / "fig4_inputs.png")
    fig.savefig(written[-1], dpi=_DPI)
    plt.close(fig)
    written.append(out_dir / "errors.png")
    from .metrics import CONVERGED_M
    _errors(written[-1], plan, styled, f"paper-group1 via {via}: true errors (grey: the loop; dotted: "
            "end of the run-up)", CONVERGED_M)
    return written


def group2_figures(out_dir: Path, plan, outcomes, via: str) -> list[Path]:
    """Figs. 5, 6, 7 of the paper and the errors, for a saturation experiment; the paths written."""
    plt = _plt()
    out_dir = Path(out_dir)
    nominal = nominal_curves(plan)
    runs = _runs(outcomes)
    styled = _style_group2(runs)
    black = dict(color="k", lw=1.0, zorder=2)
    written = []
    # Fig. 5: commanded and applied rotor forces
    n = max(len(styled), 1)
    fig, axes = plt.subplots(4, n, figsize=(4.2 * n, 9), sharex=True, sharey=True, squeeze=False)
    for j, (o, st) in enumerate(styled):
        tr = o.trace
        for r in range(4):
            ax = axes[r, j]
            ax.plot(tr.s_m, tr.rotor_command_n[:, r], color="0.55", lw=0.6, label="commanded")
            ax.plot(tr.s_m, tr.rotor_applied_n[:, r], color=st["color"], lw=0.6, label="applied")
            ax.plot(nominal["s"], nominal["rotors"][:, r], label="nominal", **black)
            if o.spec.saturation_n is not None:
                ax.axhline(o.spec.saturation_n, color="k", lw=0.6, ls="--")
            _segments(ax, plan)
            if j == 0:
                ax.set_ylabel(f"rotor {r + 1} (N)")
        axes[0, j].set_title(o.spec.label, fontsize=10)
        axes[-1, j].set_xlabel("arc length s (m)")
    if styled:
        axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle(f"paper-group2 via {via}: rotor forces, commanded (grey) and applied (colour); "
                 "nominal black, limit dashed", fontsize=11)
    fig.tight_layout()
    written.append(out_dir / "fig5_rotor_forces.png")
    fig.savefig(written[-1], dpi=75)             # 12 panels of noisy lines: kept under 200 kB
    plt.close(fig)
    # Fig. 6: paths in the p2-p3 plane, whole and the loop
    fig, (ax, zoom) = plt.subplots(1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": (2.0, 1.0)})
    _plane(ax, nominal, styled, black)
    ax.legend(fontsize=8)
    ax.set_title("paths in the p2-p3 plane", fontsize=10)
    _plane(zoom, nominal, styled, black)
    name = plan.laps_segment or "loop"
    loop = np.concatenate([plan.path.evaluate(np.linspace(a, b, 400))[0] for n, a, b in plan.segments
                           if n == name])
    e, z = loop[:, 1], -loop[:, 2]
    pad = 0.35 * (z.max() - z.min())
    zoom.set_xlim(e.min() - pad, e.max() + pad)
    zoom.set_ylim(z.min() - pad, z.max() + pad)
    zoom.set_title("the loop", fontsize=10)
    fig.suptitle(f"paper-group2 via {via}: paths", fontsize=11)
    fig.tight_layout()
    written.append(out_dir / "fig6_paths.png")
    fig.savefig(written[-1], dpi=_DPI)
    plt.close(fig)
    # Fig. 7: attitude and velocity
    written.append(out_dir / "fig7_attitude_velocity.png")
    _attitude_velocity(written[-1], plan, nominal, styled, dict(black, label="desired"),
                       f"paper-group2 via {via}: attitude and body velocity")
    written.append(out_dir / "errors.png")
    _errors(written[-1], plan, styled, f"paper-group2 via {via}: true errors (grey: the loop, every lap)", None)
    return written
