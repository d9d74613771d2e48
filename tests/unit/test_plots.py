"""The figures, checked by structure (matplotlib Agg, no pixel comparison).

A short maneuver heading north with one gate 2 m east of its line (the slalom's first gate,
scaled down) is planned once and flown once on the design model from 0.5 m off its start.
The figures must be maps (the gate to the right, at positive east), at equal scale, with
altitude up; errors on a log scale; a flight of the daemon must draw the TRUE error and,
when it failed, say why in its title and mark where; a panel without data must say so; no
text may leave the figure, and no axis label, title or tick label may cover another.
"""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, DESIGN_CONTROLLER
from mavreg.config.controller import load_controller
from mavreg.config.vehicle import load_vehicle
from mavreg.daemon.flight.phases import PHASE_CODES
from mavreg.planning.plan_io import plan_text
from mavreg.model.rotation import rpy_to_matrix, rpy_to_quat
from mavreg.plots.figures import build_flight_figure, build_plan_figure, panel
from mavreg.plots.sources import from_fly, from_simulation
from mavreg.sim.maneuver_run import fly_on_design_model
from harness.params import ONE_GATE as GATE

RATE_HZ = 250.0
OFFSET_M = (0.3, 0.3, 0.3)


@pytest.fixture(scope="module")
def plan():
    return plan_text(GATE, "one_gate.yaml", load_vehicle(DEFAULT_VEHICLE), load_controller(DESIGN_CONTROLLER))


@pytest.fixture(scope="module")
def run(plan):
    return fly_on_design_model(plan, offset_m=OFFSET_M, control_rate_hz=RATE_HZ, true_metrics=False)


@pytest.fixture(scope="module")
def plan_fig(plan):
    fig = build_plan_figure(plan)
    yield fig
    import matplotlib.pyplot as plt
    plt.close(fig)


def _line(ax, label: str):
    return next(ln for ln in ax.get_lines() if ln.get_label() == label)


def test_top_view_is_a_map_the_gate_east_is_to_the_right(plan, plan_fig):
    top = panel(plan_fig, "top")
    assert top.get_xlabel() == "east (m)" and top.get_ylabel() == "north (m)"
    x, y = (np.asarray(a) for a in _line(top, "nominal path").get_data())
    i = int(np.argmax(np.abs(x)))
    assert x[i] == pytest.approx(2.0, abs=0.15)          # the gate: 2 m east, drawn at positive x
    assert y[i] == pytest.approx(7.0, abs=0.8)           # ... 7 m north (3 m run-up + 4 m), up
    assert y[-1] > y[0] + 10                             # heading north: upwards
    (x0, x1), (y0, y1) = top.get_xlim(), top.get_ylim()
    assert x0 < x1 and y0 < y1                           # not flipped
    assert top.get_box_aspect() == pytest.approx((y1 - y0) / (x1 - x0))   # equal scale


def test_side_and_3d_views_have_altitude_up(plan_fig):
    side = panel(plan_fig, "side")
    assert side.get_ylabel() == "altitude (m)" and side.get_xlabel() == "north (m)"
    _, alt = _line(side, "nominal path").get_data()
    assert np.allclose(alt, 3.0, atol=1e-6)              # 3 m up (NED down = -3)
    ax3 = panel(plan_fig, "3d")
    assert ax3.get_zlabel() == "altitude (m)" and ax3.get_xlabel() == "east (m)"
    assert ax3.get_ylabel() == "north (m)"


def test_start_direction_and_numbered_segments_are_marked(plan, plan_fig):
    top = panel(plan_fig, "top")
    labels = [ln.get_label() for ln in top.get_lines()]
    assert "start" in labels and "end" in labels
    numbers = sorted(t.get_text() for t in top.texts if t.get_text())
    assert numbers == ["1", "2", "3"]
    arrows = [t for t in top.texts if t.get_text() == "" and t.arrow_patch is not None]
    assert len(arrows) >= 3                              # direction of travel along the path
    key = panel(plan_fig, "key")
    text = " ".join(t.get_text() for t in key.texts)
    assert all(name in text for name, _, _ in plan.segments)


def test_plan_panels_name_their_units(plan_fig):
    want = {"speed": "speed (m/s)", "thrust": "thrust (N)", "rotors": "rotor force (N)",
            "rates": "body rate (deg/s)"}
    for name, ylabel in want.items():
        ax = panel(plan_fig, name)
        assert ax.get_ylabel() == ylabel and ax.get_xlabel() == "arc length s (m)"
    assert "feasible" in plan_fig._suptitle.get_text()


def test_simulation_errors_are_on_a_log_scale(plan, run):
    fig = build_flight_figure(plan, from_simulation(plan, run, RATE_HZ, "one_gate test"))
    for name in ("transverse", "attitude"):
        ax = panel(fig, name)
        assert ax.get_yscale() == "log"
    _, e_cm = panel(fig, "transverse").get_lines()[0].get_data()
    assert np.max(e_cm) > 40.0                           # the 52 cm start ...
    assert np.min(e_cm[len(e_cm) // 2:]) < 0.4           # ... and millimetres later, both readable
    assert "completed" in fig._suptitle.get_text()
    assert panel(fig, "progress").get_xlabel() == "time (s)"
    _close(fig)


def test_a_diverged_simulation_says_why_and_where(plan):
    """60 N sideways for the first seconds, rotors capped at 4 N: the design model diverges."""
    bad = fly_on_design_model(plan, control_rate_hz=RATE_HZ, true_metrics=False, saturation_n=4.0,
                              gust_force_n=(0.0, 60.0, 0.0), gust_window_s=(1.0, 4.0))
    assert bad.metrics["status"] == "diverged"
    fig = build_flight_figure(plan, from_simulation(plan, bad, RATE_HZ, "t"))
    title = fig._suptitle.get_text()
    assert "FAILED" in title and bad.metrics["reason"][:20] in title.replace("\n", " ")
    cross = next(ln for ln in panel(fig, "top").get_lines() if ln.get_label().startswith("failed"))
    e, n = cross.get_data()
    assert (e[0], n[0]) == pytest.approx((bad.result.x[-1, 1], bad.result.x[-1, 0]))
    assert any(ln.get_label().startswith("failed here") for ln in panel(fig, "transverse").get_lines())
    _close(fig)


def _fly_logs(plan, run, phases_after: str):
    """A daemon's control log and an emulator's recording made of the design-model run:
    one second of hold, the maneuver, then ``phases_after``."""
    res = run.result
    steps = int(round(1.0 / (RATE_HZ * (res.t[1] - res.t[0]))))
    idx = np.arange(len(run.s)) * steps
    n_hold = 50
    t = np.concatenate([np.arange(n_hold) / RATE_HZ, 1.0 + res.t[idx],
                        1.0 + res.t[idx[-1]] + np.arange(1, 51) / RATE_HZ])
    code = np.concatenate([np.full(n_hold, PHASE_CODES["hold"]), np.full(len(idx), PHASE_CODES["maneuver"]),
                           np.full(50, PHASE_CODES[phases_after])]).astype(np.int8)
    x = np.concatenate([np.repeat(res.x[:1], n_hold, 0), res.x[idx], np.repeat(res.x[-1:], 50, 0)])
    nan = np.full((n_hold, 11), np.nan)
    ctrl = {"t_s": t, "phase": code, "phase_names": list(PHASE_CODES),
            "s_m": np.concatenate([np.full(n_hold, np.nan), run.s, np.full(50, np.nan)]),
            "w": np.concatenate([nan, run.w, nan[:50]]),
            "u": np.tile(plan.u[:1], (len(t), 1)), "rotor_cmd_n": np.full((len(t), 4), 1.8), "x": x}
    R = np.moveaxis(rpy_to_matrix(*x[:, 3:6].T), -1, 0)
    record = {"t_s": t, "position_ned_m": x[:, :3], "quaternion_wxyz": rpy_to_quat(*x[:, 3:6].T).T,
              "velocity_ned_m_s": np.einsum("nij,nj->ni", R, x[:, 6:9])}
    return ctrl, record


def _failure(t_s, s_m, phase="maneuver", bound="position_error"):
    return {"bound": bound, "phase": phase, "t_s": t_s, "s_m": s_m, "value": 0.52, "limit": 0.5,
            "unit": "m", "detail": "distance from the path", "action": "recovery"}


def test_fly_figure_draws_the_true_error_and_marks_the_failure(plan, run):
    ctrl, record = _fly_logs(plan, run, "recover")
    s_fail = 8.0
    t_fail = float(np.interp(s_fail, run.s, 1.0 + np.arange(len(run.s)) / RATE_HZ))
    summary = {"result": "failed", "reason": "position_error in maneuver at s=8.00 m",
               "failure": _failure(t_fail, s_fail)}
    fig = build_flight_figure(plan, from_fly(plan, ctrl, record, summary, "one_gate test"))
    trans = panel(fig, "transverse")
    true_line = next(ln for ln in trans.get_lines() if ln.get_label().startswith("TRUE"))
    own = next(ln for ln in trans.get_lines() if ln.get_label().startswith("controller's"))
    # on the design model the truth is what the controller saw: the two agree
    assert np.max(true_line.get_ydata()) == pytest.approx(np.max(own.get_ydata()), rel=0.05)
    assert "FAILED" in fig._suptitle.get_text() and "position_error" in fig._suptitle.get_text()
    fail_lines = [ln for ln in trans.get_lines() if np.allclose(ln.get_xdata(), s_fail)]
    assert fail_lines                                    # a red line where it failed
    top = panel(fig, "top")
    cross = next(ln for ln in top.get_lines() if ln.get_label().startswith("failed"))
    e, n = cross.get_data()
    i = int(np.argmin(np.abs(run.s - s_fail)))
    assert (e[0], n[0]) == pytest.approx((run.result.x[i * 4, 1], run.result.x[i * 4, 0]), abs=0.05)
    timeline = panel(fig, "timeline")
    assert any(ln.get_label().startswith("failed") for ln in timeline.get_lines())
    # before and after the maneuver are two pieces: no straight line from its start to its end
    outside = _line(top, "outside the maneuver").get_xdata()
    assert np.isnan(outside).sum() == 1 and 0 < int(np.flatnonzero(np.isnan(outside))[0]) < len(outside) - 1
    _close(fig)


def test_a_flight_that_succeeded_has_no_failure_mark(plan, run):
    ctrl, record = _fly_logs(plan, run, "land")
    fig = build_flight_figure(plan, from_fly(plan, ctrl, record, {"result": "ok", "failure": None}, "t"))
    assert "FAILED" not in fig._suptitle.get_text()
    for ax in fig.axes:
        assert not any(ln.get_label().startswith("failed") for ln in ax.get_lines())
    _close(fig)


def test_without_a_recording_the_figure_says_it_shows_the_controllers_view(plan, run):
    """A real vehicle (--vehicle) has no ground truth: nothing may be labelled TRUE."""
    ctrl, _ = _fly_logs(plan, run, "land")
    fig = build_flight_figure(plan, from_fly(plan, ctrl, None, {"result": "ok", "failure": None}, "t"))
    labels = [ln.get_label() for ax in fig.axes for ln in ax.get_lines()]
    assert not any(lab.startswith("TRUE") for lab in labels)
    assert "controller's state (maneuver)" in labels
    assert panel(fig, "timeline").get_lines()[0].get_label() == "altitude (controller's state)"
    _close(fig)


def test_a_refused_flight_says_so_in_every_panel_it_cannot_fill(plan, run):
    ctrl, record = _fly_logs(plan, run, "land")
    hold = ctrl["phase"] == PHASE_CODES["hold"]
    ctrl = {k: (v[hold] if isinstance(v, np.ndarray) else v) for k, v in ctrl.items()}
    record = {k: v[hold] for k, v in record.items()}
    summary = {"result": "failed", "reason": "gate_thrust in hold", "failure":
               _failure(float(ctrl["t_s"][-1]), None, "hold", "gate_thrust")}
    fig = build_flight_figure(plan, from_fly(plan, ctrl, record, summary, "t"))
    for name in ("transverse", "attitude", "speed", "thrust", "rotors"):
        ax = panel(fig, name)
        assert "no maneuver flown" in " ".join(t.get_text() for t in ax.texts), name
    for ax in fig.axes:
        assert ax.has_data() or ax.texts or ax.get_label() == "key", ax.get_label()
    assert any(ln.get_label().startswith("failed") for ln in panel(fig, "top").get_lines())
    _close(fig)


def _drawn_ticklabels(axis):
    lo, hi = sorted(axis.get_view_interval())
    return [tick.label1 for tick, loc in zip(axis.get_major_ticks(), axis.get_majorticklocs())
            if lo - 1e-9 <= loc <= hi + 1e-9 and tick.label1.get_visible() and tick.label1.get_text()]


def test_no_text_is_cut_off_or_covers_another(plan, run, plan_fig):
    fig = build_flight_figure(plan, from_simulation(plan, run, RATE_HZ, "x " * 90))   # a long title wraps
    for f in (plan_fig, fig):
        f.canvas.draw()
        r = f.canvas.get_renderer()
        page = f.bbox
        boxes = [(ax.get_label(), ax.get_tightbbox(r)) for ax in f.axes]
        boxes.append(("title", f._suptitle.get_window_extent(r)))
        for name, bb in boxes:                # every drawn label, tick and legend of a panel
            assert bb.x0 >= page.x0 - 1 and bb.x1 <= page.x1 + 1 and bb.y0 >= page.y0 - 1 \
                and bb.y1 <= page.y1 + 1, f"{name} is cut off: {bb} outside {page}"
        for i, (na, a) in enumerate(boxes):    # no panel (with its labels) reaches into another
            for nb, b in boxes[i + 1:]:
                assert not a.overlaps(b), f"{na} and {nb} overlap"
        labels = [f._suptitle]
        for ax in f.axes:
            if ax.name == "3d":
                labels += [ax.xaxis.label, ax.yaxis.label, ax.zaxis.label, ax.title]
            if ax.name == "3d" or not ax.axison:
                continue
            labels += [ax.xaxis.label, ax.yaxis.label, ax.title]
            for axis in (ax.xaxis, ax.yaxis):
                ticks = [tl.get_window_extent(r) for tl in _drawn_ticklabels(axis)]
                for a, b in zip(ticks, ticks[1:]):
                    assert not a.overlaps(b), f"tick labels collide in {ax.get_label()}"
                labels += _drawn_ticklabels(axis)
        texts = [(t.get_text(), t.get_window_extent(r)) for t in labels if t.get_text()]
        for i, (ta, a) in enumerate(texts):
            for tb, b in texts[i + 1:]:
                assert not a.overlaps(b), f"{ta!r} covers {tb!r}"
    _close(fig)


def _close(fig):
    import matplotlib.pyplot as plt
    plt.close(fig)
