"""The figures: a plan's nominal (``mavreg plan --plot``) and a flight (``simulate --plot``,
``fly``'s ``flight.png``).

Layout: the top row holds the 3-D, top and side views (:mod:`.views`); below, panels
against arc length s, two a row, segment boundaries drawn and numbered as in the views.
Errors are on a log scale, so a start 85 cm off the path does not flatten the millimetres
that follow. A failed flight says why in its title and is marked where it failed (a red
cross in the views, a red line in the panels); a panel with nothing to draw says so.
"""
from __future__ import annotations

import numpy as np

from ..config.vehicle import G

from ..maneuver.nominal_table import nominal_table, nominal_time_s, rotor_forces_n
from .panels import (ERROR_FLOOR_CM, clip_spike, ERROR_FLOOR_DEG, error_panel, mark_failure_s, mark_segments, new_figure,
                     no_data, save, title_lines)
from .sources import FlightData
from .views import ViewLine, draw_views, views_height_in

__all__ = ["plan_figure", "flight_figure", "build_plan_figure", "build_flight_figure", "panel"]

_NOMINAL = dict(color="0.35", ls="--", lw=1.0)
_ROTOR_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red")
_ROTOR_NAMES = ("1 front", "2 right", "3 back", "4 left")
_FAIL_MARK = dict(marker="X", color="tab:red", ms=11, mec="white", mew=0.8)
_MAX_POINTS = 3000
_PANEL_IN = 3.4
"""Height of a row of panels against s (inches)."""


def _thin(a, n: int = _MAX_POINTS):
    return a[::max(1, len(a) // n)]


def _view_cells(fig, gs):
    """The four cells of the views' row: 3-D, top, side, key."""
    sub = gs[0, :].subgridspec(1, 5, width_ratios=[1.25, 0.1, 1.15, 1.15, 0.55])
    return [sub[0, k] for k in (0, 2, 3, 4)]      # column 1 keeps the 3-D view's labels off the next


def _reference(plan):
    x = _thin(plan.x[:, :3])
    starts = np.array([plan.x[min(np.searchsorted(plan.s, a), len(plan.s) - 1), :3] for _, a, _ in plan.segments])
    return np.vstack([x, plan.x[-1:, :3]]), starts


def _rotor_panel(ax, s, rotors, plan, label_prefix: str) -> None:
    for k in range(4):
        ax.plot(s, rotors[:, k], color=_ROTOR_COLOURS[k], lw=0.8, label=f"{label_prefix}rotor {_ROTOR_NAMES[k]}")
    limit = plan.vehicle.max_rotor_thrust_n
    ax.axhline(limit, color="k", ls=":", lw=0.9, label=f"limit {limit:g} N")
    ax.axhline(0.0, color="k", ls=":", lw=0.6)
    over = (rotors.max(axis=1) > limit) | (rotors.min(axis=1) < 0)
    if np.any(over):
        ax.fill_between(s, 0, limit, where=over, color="tab:red", alpha=0.15, label="beyond the rotors")
    ax.set_ylabel("rotor force (N)")


def _legend(ax, **kw) -> None:
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7, **kw)


def panel(fig, name: str):
    """The axes of a figure labelled ``name`` ('top', 'side', '3d', 'key', 'transverse',
    'attitude', 'speed', 'thrust', 'rotors', 'rates', 'timeline', 'progress')."""
    for ax in fig.axes:
        if ax.get_label() == name:
            return ax
    raise KeyError(name)


def _name(**axes) -> None:
    for name, ax in axes.items():
        ax.set_label(name)


def plan_figure(png_path, plan, note: str = "", violations=None) -> None:
    """Save :func:`build_plan_figure`."""
    save(build_plan_figure(plan, note, violations), png_path)


def build_plan_figure(plan, note: str = "", violations=None):
    """The plan's figure: its path in the three views, speed, thrust, rotor forces and
    body rates against s (:func:`~mavreg.maneuver.nominal_table.nominal_table`'s columns).
    ``violations`` (default: the plan's feasibility's) are listed in red in the title."""
    table = nominal_table(plan)
    ref, starts = _reference(plan)
    top_in = views_height_in(ref)
    fig, gs = new_figure(top_in + 2 * _PANEL_IN, [top_in, _PANEL_IN, _PANEL_IN])
    draw_views(fig, _view_cells(fig, gs), ref, starts, [n for n, _, _ in plan.segments], [])
    s = _thin(table["s_m"])
    speed = fig.add_subplot(gs[1, 0:3])
    thrust = fig.add_subplot(gs[1, 3:6], sharex=speed)
    rotors = fig.add_subplot(gs[2, 0:3], sharex=speed)
    rates = fig.add_subplot(gs[2, 3:6], sharex=speed)
    _name(speed=speed, thrust=thrust, rotors=rotors, rates=rates)
    speed.plot(s, _thin(table["speed_m_s"]), color="tab:blue", lw=1.0)
    speed.set_ylabel("speed (m/s)")
    thrust.plot(s, _thin(table["thrust_n"]), color="tab:blue", lw=1.0, label="collective thrust")
    weight = plan.vehicle.mass_kg * G
    thrust.axhline(weight, color="k", ls=":", lw=0.8, label=f"weight {weight:.2f} N")
    thrust.set_ylabel("thrust (N)")
    _rotor_panel(rotors, s, _thin(table["rotor_forces_n"]), plan, "")
    for k, name in enumerate(("roll rate p", "pitch rate q", "yaw rate r")):
        rates.plot(s, np.degrees(_thin(table["body_rates_rad_s"][:, k])), lw=0.9, label=name)
    rates.set_ylabel("body rate (deg/s)")
    for ax in (speed, thrust, rotors, rates):
        mark_segments(ax, plan.segments, numbers_on_top=ax in (speed, thrust))
    for ax in (speed, thrust, rotors, rates):
        ax.set_xlabel("arc length s (m)")
    for ax in (thrust, rotors, rates):
        _legend(ax, loc="best", ncol=2)
    bad = list(plan.feasibility.violations if violations is None else violations)
    verdict = "feasible" if not bad else "INFEASIBLE"
    fig.suptitle(title_lines(f"{plan.name}: nominal plan, {plan.length_m:.1f} m in "
                             f"{float(table['t_s'][-1]):.1f} s ({verdict})", note,
                             *(f"violation: {v}" for v in bad)),
                 color="k" if not bad else "tab:red",
                 fontsize=10)
    return fig


def _error_axes(ax, series, floor, scale, ylabel, fd, plan) -> None:
    if not series or all(se.s_m.size == 0 for se in series):
        no_data(ax, fd.no_maneuver)
        ax.set_ylabel(ylabel)
        return
    styles = [dict(color="tab:red", lw=1.0, zorder=4), dict(color="tab:blue", lw=0.6, alpha=0.7, zorder=3)]
    top = floor
    for se, st in zip(series, styles):
        error_panel(ax, se.s_m, scale * se.values, floor, st, se.label)
        if se.values.size:
            top = max(top, float(np.nanmax(scale * se.values)))
    ax.set_ylim(top=top * 30)          # a decade and a half of headroom: the legend covers no data
    ax.set_ylabel(ylabel)
    ax.set_xlabel("arc length s (m)")
    mark_segments(ax, plan.segments, numbers_on_top=True)
    _legend(ax, loc="upper right")


def _nominal_vs(ax, s_grid, values, flown, ylabel) -> None:
    ax.plot(_thin(s_grid), _thin(values), label="nominal", **_NOMINAL)
    if flown is not None and flown.s_m.size:
        ax.plot(flown.s_m, flown.values, color="tab:blue", lw=0.9, label=flown.label)
    ax.set_ylabel(ylabel)


def _state_panels(fig, gs, plan, fd: FlightData):
    speed = fig.add_subplot(gs[2, 0:3])
    thrust = fig.add_subplot(gs[2, 3:6], sharex=speed)
    rotors = fig.add_subplot(gs[3, 0:3], sharex=speed)
    _name(speed=speed, thrust=thrust, rotors=rotors)
    if fd.speed_m_s is None and fd.thrust_n is None:
        for ax in (speed, thrust, rotors):
            no_data(ax, fd.no_maneuver)
        speed.set_ylabel("speed (m/s)")
        thrust.set_ylabel("thrust (N)")
        rotors.set_ylabel("rotor force (N)")
        return speed, thrust, rotors
    _nominal_vs(speed, plan.s, plan.speed_m_s, fd.speed_m_s, "speed (m/s)")
    _nominal_vs(thrust, plan.s, plan.u[:, 0], fd.thrust_n, "thrust (N)")
    _rotor_panel(rotors, fd.rotors_n.s_m, fd.rotors_n.values, plan, f"{fd.rotors_n.label} ")
    nominal_rotors = rotor_forces_n(plan)
    clip_spike(rotors, fd.rotors_n.s_m, fd.rotors_n.values,
               1.3 * max(plan.vehicle.max_rotor_thrust_n, float(nominal_rotors.max())), "N")
    clip_spike(thrust, fd.thrust_n.s_m, fd.thrust_n.values, 1.5 * float(plan.u[:, 0].max()), "N")
    for ax in (speed, thrust, rotors):
        mark_segments(ax, plan.segments)
        _legend(ax, loc="best", ncol=2 if ax is rotors else 1)
    for ax in (speed, thrust, rotors):
        ax.set_xlabel("arc length s (m)")
    return speed, thrust, rotors


def _progress_panel(ax, plan, fd: FlightData) -> None:
    t, s = fd.progress
    ax.plot(_thin(nominal_time_s(plan)), _thin(plan.s), label="nominal schedule", **_NOMINAL)
    ax.plot(t, s, color="tab:blue", lw=0.9, label="flown")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("arc length s (m)")
    ax.grid(color="0.9", lw=0.6)
    _legend(ax, loc="upper left")


_PHASE_COLOURS = {"preflight": "0.9", "takeoff": "#cfe2f3", "hold": "#d9ead3", "run_in": "#fff2cc",
                  "maneuver": "#f4cccc", "land": "#d9d2e9", "recover": "#f9cb9c", "aborted": "#eeeeee",
                  "disarmed": "0.95", "terminate": "#ea9999"}


def _timeline_panel(ax, fd: FlightData) -> None:
    tl = fd.timeline
    seen = set()
    for name, a, b in tl["phases"]:
        ax.axvspan(a, b, color=_PHASE_COLOURS.get(name, "0.9"), lw=0, zorder=0,
                   label=None if name in seen else name)
        seen.add(name)
    ax.plot(_thin(tl["t_s"]), _thin(tl["altitude_m"]), color="k", lw=0.9, label=tl["label"])
    if fd.failure and fd.failure.get("t_s") is not None:
        ax.axvline(fd.failure["t_s"], color="tab:red", lw=1.3, label=f"failed: {fd.failure['text']}")
    ax.set_xlabel("vehicle time (s)")
    ax.set_ylabel("altitude (m)")
    ax.set_title("the whole flight, by phase", fontsize=9)
    ax.grid(color="0.9", lw=0.6)
    _legend(ax, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=4)


def flight_figure(png_path, plan, fd: FlightData) -> None:
    """Save :func:`build_flight_figure`."""
    save(build_flight_figure(plan, fd), png_path)


def build_flight_figure(plan, fd: FlightData):
    """A flight's figure (see the module's docstring)."""
    ref, starts = _reference(plan)
    top_in = views_height_in(ref, [a for a in (fd.maneuver_ned, fd.other_ned) if a is not None])
    fig, gs = new_figure(top_in + 3 * _PANEL_IN, [top_in, _PANEL_IN, _PANEL_IN, _PANEL_IN])
    lines = []
    if fd.other_ned is not None and len(fd.other_ned):
        lines.append(ViewLine(fd.other_ned, "outside the maneuver", color="0.7", lw=0.7))
    if len(fd.maneuver_ned):
        lines.append(ViewLine(fd.maneuver_ned, fd.maneuver_label, color="tab:blue", lw=1.1))
    fail = fd.failure
    marks = [(fail["ned"], f"failed: {fail['text']}", _FAIL_MARK)] if fail and fail.get("ned") is not None else []
    draw_views(fig, _view_cells(fig, gs), ref, starts, [n for n, _, _ in plan.segments], lines, marks)
    trans = fig.add_subplot(gs[1, 0:3])
    att = fig.add_subplot(gs[1, 3:6], sharex=trans)
    _name(transverse=trans, attitude=att)
    _error_axes(trans, fd.transverse_m, ERROR_FLOOR_CM, 100.0, "transverse error (cm, log)", fd, plan)
    _error_axes(att, fd.attitude_deg, ERROR_FLOOR_DEG, 1.0, "attitude error (deg, log)", fd, plan)
    speed, thrust, rotors = _state_panels(fig, gs, plan, fd)
    last = fig.add_subplot(gs[3, 3:6])
    if fd.timeline is not None:
        _timeline_panel(last, fd)
        last.set_label("timeline")
    elif fd.progress is not None:
        _progress_panel(last, plan, fd)
        last.set_label("progress")
    else:
        no_data(last, "no schedule or timeline recorded")
    if fail:
        s_f = fail.get("s_m")
        label = f"failed here (s = {s_f:.2f} m)" if s_f is not None and np.isfinite(s_f) else None
        for ax in (trans, att, speed, thrust, rotors):
            mark_failure_s(ax, s_f, label if ax is trans else None)
        _legend(trans, loc="upper right")
    fig.suptitle(title_lines(fd.heading, fd.outcome), fontsize=10, color="k" if fd.ok else "tab:red")
    return fig
