"""Nearest-point projection: continuous through laps and self-approaches, extension, tube."""
from __future__ import annotations

import numpy as np
import pytest

from mavreg.config.paths import maneuver_file
from mavreg.config.maneuver import load_maneuver, load_maneuver_text
from mavreg.geometry.build import build_path
from mavreg.geometry.projection import Projector

R = 2.0
CIRCLE = f"""\
kind: maneuver
version: 1
name: circle
start: {{position_m: [0, 0, -5], heading_deg: 0}}
segments:
  - name: ring
    arc: {{radius_m: {R}, angle_deg: 360, bend_deg: 90}}   # level, turning right
speed: {{initial_m_s: 3.0}}
laps: {{segment: ring, count: 3}}
"""


@pytest.fixture(scope="module")
def circle():
    return build_path(load_maneuver_text(CIRCLE, "circle.yaml"))


def _offset_points(path, sigma, a1, a2):
    c, F = path.evaluate(sigma)[:2]
    return c + a1[:, None] * F[:, :, 1] + a2[:, None] * F[:, :, 2]


def test_three_lap_circle_is_three_laps_long(circle):
    assert circle.length_m == pytest.approx(3 * 2 * np.pi * R)
    c = circle.evaluate(np.array([0.0, 2 * np.pi * R, 4 * np.pi * R, circle.length_m]))[0]
    np.testing.assert_allclose(c - c[0], 0.0, atol=1e-8)   # it really goes round 3 times


def test_s_increases_continuously_through_all_laps(circle):
    sigma = np.arange(0.0, circle.length_m, 0.02)
    # off the path by a few cm, varying: in and out of the circle, above and below it
    a1 = 0.05 * np.sin(sigma)
    a2 = 0.10 * np.cos(0.7 * sigma)
    pts = _offset_points(circle, sigma, a1, a2)
    proj = Projector(circle)
    first = proj.reset(pts[0], 0.0)
    assert first.s == pytest.approx(0.0, abs=1e-6)
    s = [first.s]
    for y in pts[1:]:
        p = proj.update(y)
        assert p.in_tube
        s.append(p.s)
    s = np.array(s)
    ds = np.diff(s)
    assert np.all(ds > 0) and np.max(ds) < 0.03            # no jump to another lap
    np.testing.assert_allclose(s, sigma, atol=1e-6)         # the offset is normal to t(sigma)
    assert s[-1] == pytest.approx(circle.length_m, abs=0.03)


@pytest.fixture(scope="module")
def barrel_path():
    return build_path(load_maneuver(maneuver_file("barrel_roll")))


def test_s_stays_on_its_branch_at_the_barrel_roll_self_approach(barrel_path):
    path = barrel_path
    sig = path.s_nodes
    c = path.c_nodes
    # The loop's bottom: entry and exit pass close to each other, far apart in s.
    i = np.arange(0, len(sig), 4)
    d = np.linalg.norm(c[i][:, None] - c[i][None, :], axis=2)
    far = np.abs(sig[i][:, None] - sig[i][None, :]) > 5.0
    dmin = np.where(far, d, np.inf)
    a, b = np.unravel_index(np.argmin(dmin), dmin.shape)
    assert dmin[a, b] < 0.6, "the barrel roll should come back close to its entry"
    s_a, s_b = sorted((sig[i][a], sig[i][b]))
    # Fly the whole path slightly off it; s follows sigma, never switching branch.
    sigma = np.arange(0.0, path.length_m, 0.01)
    pts = _offset_points(path, sigma, 0.04 * np.sin(2 * sigma), 0.04 * np.cos(3 * sigma))
    proj = Projector(path)
    proj.reset(pts[0], 0.0)
    s = np.array([proj.update(y).s for y in pts])
    np.testing.assert_allclose(s, sigma, atol=1e-5)
    # Started near each branch with a guess, it locks onto that branch.
    for s_here in (s_a, s_b):
        y = path.point(s_here).position + 0.03 * path.point(s_here).frame[:, 2]
        assert Projector(path).reset(y, s_guess=s_here).s == pytest.approx(s_here, abs=1e-4)


def test_point_behind_the_start_projects_onto_the_extension(barrel_path):
    # (on the circle a point 1 m behind the start is nearer the circle than the extension)
    p0 = barrel_path.point(0.0)
    y = p0.position - 1.0 * p0.frame[:, 0] + 0.02 * p0.frame[:, 1]
    proj = Projector(barrel_path).reset(y, 0.0)
    assert proj.s == pytest.approx(-1.0, abs=1e-6)
    assert proj.distance_m == pytest.approx(0.02, abs=1e-9)


def test_beyond_the_centre_of_the_circle_is_outside_the_tube(circle):
    s0 = 3.0
    p = circle.point(s0)
    inward = p.frame[:, 1:] @ p.k / np.linalg.norm(p.k)     # towards the centre
    proj = Projector(circle)
    proj.reset(p.position, s0)
    for a in np.linspace(0.0, 1.5 * R, 61):
        out = proj.update(p.position + a * inward)
        if a <= 0.5 * R:
            assert out.in_tube, a
        if a >= 1.05 * R:
            assert not out.in_tube, a


@pytest.mark.skipif(not __import__("mavreg.accel", fromlist=["x"]).ACCELERATED, reason="numba is not in use")
def test_the_compiled_series_gives_the_update_by_update_answers(barrel_path):
    """``Projector.series`` (one compiled loop) against reset-then-update in Python, on a
    wandering flight: before the start, through the self-approach, past the end, out of the
    tube. Same arc lengths and distances to 1e-9 m; a path shifted 1 mm is a negative control."""
    path = barrel_path
    sigma = np.linspace(-1.0, path.length_m + 1.0, 4000)
    rng = np.random.default_rng(3)
    a1 = 0.3 * np.sin(0.9 * sigma) + 0.02 * rng.standard_normal(sigma.size)
    a2 = 0.2 * np.cos(0.4 * sigma)
    pts = _offset_points(path, np.clip(sigma, 0.0, path.length_m), a1, a2)
    tangents = path.evaluate(np.array([0.0, path.length_m]))[1][:, :, 0]
    pts[sigma < 0] += np.outer(sigma[sigma < 0], tangents[0])                  # the extensions
    after = sigma > path.length_m
    pts[after] += np.outer(sigma[after] - path.length_m, tangents[1])
    s_ref, d_ref = Projector(path).series(pts, compiled=False)
    proj = Projector(path)
    s, d = proj.series(pts, compiled=True)
    np.testing.assert_allclose(s, s_ref, rtol=0, atol=1e-9)
    np.testing.assert_allclose(d, d_ref, rtol=0, atol=1e-9)
    assert proj.s == s[-1] and s[0] < 0.0 < path.length_m < s[-1]
    s_off, _ = Projector(path).series(pts + [0.0, 0.0, 1e-3], compiled=True)
    assert np.abs(s_off - s_ref).max() > 1e-6
