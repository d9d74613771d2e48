"""Planning's budget, estimated before anything is allocated (mavreg.maneuver.budget), and the
keys that must act on a plan: a change's offset within its segment, limits.max_tilt_deg."""
from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pytest

from mavreg.config.paths import DEFAULT_VEHICLE, DESIGN_CONTROLLER, maneuver_file
from mavreg.config.controller import load_controller
from mavreg.config.maneuver import load_maneuver, load_maneuver_text
from mavreg.config.vehicle import load_vehicle
from mavreg.errors import UsageError
from mavreg.geometry.build import build_path
from mavreg.maneuver import plan as pm
from mavreg.maneuver import nominal_grid as ng
from mavreg.maneuver.budget import MAX_PLAN_BYTES, PlanBudgetError, check_budget, estimate
from mavreg.planning.cache import PlanCache
from mavreg.maneuver.feasibility import check_feasibility

BARREL_TEXT = maneuver_file("barrel_roll").read_text()
BARREL = load_maneuver(maneuver_file("barrel_roll"))
VEHICLE = load_vehicle(DEFAULT_VEHICLE)
CONTROLLER = load_controller(DESIGN_CONTROLLER)


@pytest.mark.parametrize("name", ["barrel_roll", "slalom"])
def test_the_estimate_matches_the_grid_the_planner_builds(name):
    """The node counts from the file alone against the path and the time grid built (the
    slalom's waypoint curve is a little longer than its polygon)."""
    spec = load_maneuver(maneuver_file(name))
    est = estimate(spec, CONTROLLER.riccati_step_s)
    path = build_path(spec)
    speed, _ = pm.build_profiles(spec, path)
    grid = ng.with_midpoints(ng.time_grid(path, speed, CONTROLLER.riccati_step_s))
    assert est.length_m == pytest.approx(path.length_m, rel=0.02)
    assert est.path_nodes == pytest.approx(len(path.s_nodes), rel=0.02)
    assert est.grid_nodes == pytest.approx(len(grid), rel=0.01)
    assert est.fits


def test_too_many_laps_is_refused_before_anything_is_allocated():
    tracemalloc.start()
    try:
        with pytest.raises(PlanBudgetError, match="too many laps: 100 laps of 'loop'") as err:
            pm.plan_spec(BARREL.with_laps(100), VEHICLE, CONTROLLER)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 5e6, peak
    most = int(str(err.value).rsplit("at most ", 1)[1].split()[0])
    assert estimate(BARREL.with_laps(most), CONTROLLER.riccati_step_s).fits
    assert not estimate(BARREL.with_laps(most + 1), CONTROLLER.riccati_step_s).fits


def test_too_fine_a_step_and_too_long_are_named():
    with pytest.raises(PlanBudgetError, match="too fine a step: riccati_step_s 0.0001 s"):
        check_budget(BARREL, 1e-4)
    long = load_maneuver_text(BARREL_TEXT.replace("length_m: 18.0", "length_m: 1000"))
    with pytest.raises(PlanBudgetError, match="too long: 1022 m"):
        check_budget(long, CONTROLLER.riccati_step_s)
    assert estimate(long, CONTROLLER.riccati_step_s).bytes > MAX_PLAN_BYTES


@pytest.mark.parametrize("change, match", [
    ("offset_m: 0.0, length_m: 10.0, to_m_s: 8.0", "'run_up' at offset_m 500 lies beyond the segment's 18.00 m"),
    ("anchor: end, offset_m: 1.5", "'loop' at offset_m 500 lies beyond the segment's 10.47 m"),
])
def test_a_change_beyond_its_segment_is_refused_not_dropped(change, match):
    spec = load_maneuver_text(BARREL_TEXT.replace(change, change.replace(
        "offset_m: 0.0" if "0.0" in change else "offset_m: 1.5", "offset_m: 500")))
    with pytest.raises(UsageError, match=match):
        pm.plan_spec(spec, VEHICLE, CONTROLLER)


def _attitudes(tilts_deg):
    """Body-to-NED matrices pitched by each angle (the body z axis tilted from down)."""
    out = []
    for a in np.radians(tilts_deg):
        c, s = math.cos(a), math.sin(a)
        out.append([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array(out)


def test_max_tilt_makes_the_nominal_infeasible_where_it_tilts_further():
    s = np.linspace(0.0, 3.0, 4)
    u = np.tile([10.0, 0, 0, 0], (4, 1))
    rotors = np.full((4, 4), 2.5)
    args = (s, u, rotors, np.full(4, 5.0), 10.0, 0.2, lambda q: "seg")
    R = _attitudes([0, 20, 50, 0])
    assert check_feasibility(*args, R, math.radians(60)).feasible
    feas = check_feasibility(*args, R, math.radians(30))
    assert not feas.feasible
    assert feas.violations[0].startswith("tilt 50.0 deg > limits.max_tilt_deg 30.0 at s = 2.00 m")


def test_max_tilt_of_the_file_reaches_the_plan():
    """The forward loop pitches through 90 deg: with limits.max_tilt_deg 10 it is infeasible
    (no gains are computed for it), without it feasible."""
    text = maneuver_file("forward_loop").read_text().replace("yaw:", "limits: {max_tilt_deg: 10}\nyaw:")
    plan = pm.plan_spec(load_maneuver_text(text), VEHICLE, CONTROLLER, strict=False)
    assert not plan.feasibility.feasible
    assert any(v.startswith("tilt ") and "max_tilt_deg 10.0" in v for v in plan.feasibility.violations)


def test_body_rates_beyond_the_autopilots_limit_make_a_plan_infeasible():
    """With rates to an autopilot the output clips every rate at ``max_body_rate_rad_s``: the
    forward loop's nominal pitch rate (5.7 rad/s at its top) is refused at PX4's default
    220 deg/s, named by axis and where; the rotors output does not check it."""
    from dataclasses import replace as dc_replace

    from mavreg.config.vehicle import RateInterfaceParams
    loop = load_maneuver(maneuver_file("forward_loop"))
    rates = dc_replace(VEHICLE, output="rates", rate_interface=RateInterfaceParams(
        hover_thrust=0.2, max_body_rate_rad_s=(3.84, 3.84, 3.5)))
    plan = pm.plan_spec(loop, rates, CONTROLLER, strict=False)
    assert not plan.feasibility.feasible
    bad = [v for v in plan.feasibility.violations if v.startswith("pitch rate ")]
    assert bad and "max_body_rate_rad_s 3.84" in bad[0] and "'loop'" in bad[0]
    fast = dc_replace(rates, rate_interface=dc_replace(rates.rate_interface, max_body_rate_rad_s=(12.0, 12.0, 6.0)))
    assert not any("rate" in v for v in pm.plan_spec(loop, fast, CONTROLLER, strict=False).feasibility.violations)


def test_the_cache_keeps_its_byte_cap(tmp_path):
    """Entries of 40 kB under a 100 kB cap: the newest two stay; one over half the cap is
    not stored at all."""
    cache = PlanCache(tmp_path, max_bytes=100_000)
    for i in range(5):
        assert cache.get_or_plan((i,), lambda: b"x" * 40_000) == b"x" * 40_000
        assert not cache.last_hit
    assert cache.size_bytes() <= 100_000
    assert cache.get_or_plan((4,), lambda: None) == b"x" * 40_000 and cache.last_hit
    cache.get_or_plan(("big",), lambda: b"y" * 60_000)
    cache.get_or_plan(("big",), lambda: b"z")
    assert not cache.last_hit and cache.size_bytes() <= 100_000


def test_the_cache_cap_from_the_environment(monkeypatch, tmp_path):
    from mavreg.planning.cache import MAX_BYTES, default_cache
    monkeypatch.setenv("MAVREG_PLAN_CACHE", str(tmp_path))
    monkeypatch.delenv("MAVREG_PLAN_CACHE_MAX_MB", raising=False)
    assert default_cache().max_bytes == MAX_BYTES
    monkeypatch.setenv("MAVREG_PLAN_CACHE_MAX_MB", "64")
    assert default_cache().max_bytes == 64 * 2 ** 20
    monkeypatch.setenv("MAVREG_PLAN_CACHE_MAX_MB", "lots")
    with pytest.raises(ValueError, match="MAVREG_PLAN_CACHE_MAX_MB='lots': expected a size in MiB"):
        default_cache()
