"""Path geometry: arc length, rotation-minimizing frame, closed arcs, helices, C2 blends."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mavreg.config.maneuver import load_maneuver_text
from mavreg.errors import ManeuverError
from mavreg.geometry.build import build_path, start_frame
from mavreg.geometry.path import Path
from mavreg.geometry.segments import arc_piece, blend_piece, helix_piece, line_piece

FRAME0 = start_frame(0.3, 0.2)
ORIGIN = np.array([1.0, -2.0, -3.0])

unit_dir = st.floats(-np.pi, np.pi).map(lambda b: np.array([np.cos(b), np.sin(b)]))


@st.composite
def piece(draw, i):
    kind = draw(st.sampled_from(["line", "arc", "helix", "blend"]))
    name = f"{kind}{i}"
    if kind == "line":
        return line_piece(name, draw(st.floats(0.2, 3.0)))
    if kind == "arc":
        return arc_piece(name, draw(st.floats(0.5, 5.0)), draw(st.floats(0.1, 3.0)), draw(unit_dir))
    if kind == "helix":
        return helix_piece(name, draw(st.floats(0.5, 3.0)), draw(st.floats(-3.0, 3.0)),
                           draw(st.floats(0.2, 3.0)), draw(unit_dir))
    kv = st.lists(st.floats(-1.0, 1.0), min_size=2, max_size=2).map(np.array)
    return blend_piece(name, draw(st.floats(0.5, 3.0)), (draw(kv), draw(kv), draw(kv)),
                       (draw(kv), draw(kv), draw(kv)))


@st.composite
def random_path(draw):
    n = draw(st.integers(1, 3))
    return Path([draw(piece(i)) for i in range(n)], ORIGIN, FRAME0, spacing_m=0.005)


def _interior_s(path, rng, n=20, margin=1e-3):
    """Samples away from the ends and from the piece junctions (where random pieces may
    have a curvature jump, so that central differences of c are only O(h) there)."""
    s = rng.uniform(margin, path.length_m - margin, n)
    edges = np.array([sp.s_start_m for sp in path.spans])
    keep = np.min(np.abs(s[:, None] - edges[None, :]), axis=1) > margin
    return s[keep] if keep.any() else np.array([path.length_m / 2])


@settings(max_examples=12, deadline=None)
@given(random_path(), st.integers(0, 2**31))
def test_unit_speed_and_orthonormal_right_handed_frames(path, seed):
    s = _interior_s(path, np.random.default_rng(seed))
    h = 1e-4
    cp, Fp = path.evaluate(s + h)[:2]
    cm = path.evaluate(s - h)[0]
    speed = np.linalg.norm((cp - cm) / (2 * h), axis=1)
    np.testing.assert_allclose(speed, 1.0, atol=2e-5)  # cubic Hermite between nodes
    c, F = path.evaluate(s)[:2]
    np.testing.assert_allclose(np.einsum("nji,njk->nik", F, F), np.broadcast_to(np.eye(3), F.shape),
                               atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-6)
    # the tangent column is the direction of motion (the frame and the position are
    # interpolated separately between nodes; they agree to O(spacing^3 * curvature terms))
    np.testing.assert_allclose(F[:, :, 0], (cp - cm) / (2 * h), atol=1e-4)


@settings(max_examples=12, deadline=None)
@given(random_path(), st.integers(0, 2**31))
def test_rotation_minimizing_frame_equations(path, seed):
    """t' = k1 m1 + k2 m2 and m_i' = -k_i t: the normals do not twist about t."""
    s = _interior_s(path, np.random.default_rng(seed), margin=1e-2)
    h = 1e-4
    Fp, Fm = path.evaluate(s + h)[1], path.evaluate(s - h)[1]
    dF = (Fp - Fm) / (2 * h)
    _, F, k = path.evaluate(s)[:3]
    t, m1, m2 = F[:, :, 0], F[:, :, 1], F[:, :, 2]
    np.testing.assert_allclose(dF[:, :, 0], k[:, :1] * m1 + k[:, 1:] * m2, atol=1e-4)
    np.testing.assert_allclose(dF[:, :, 1], -k[:, :1] * t, atol=1e-4)
    np.testing.assert_allclose(dF[:, :, 2], -k[:, 1:] * t, atol=1e-4)


@settings(max_examples=15, deadline=None)
@given(st.floats(0.3, 5.0), unit_dir)
def test_full_arc_is_a_closed_circle(radius, direction):
    path = Path([arc_piece("loop", radius, 2 * np.pi, direction)], ORIGIN, FRAME0)
    assert path.length_m == pytest.approx(2 * np.pi * radius)
    assert path.closed
    c, F = path.evaluate(np.array([0.0, path.length_m]))[:2]
    np.testing.assert_allclose(c[1], c[0], atol=1e-9)
    np.testing.assert_allclose(F[1], F[0], atol=1e-9)
    normal = direction[0] * FRAME0[:, 1] + direction[1] * FRAME0[:, 2]
    centre = ORIGIN + radius * normal
    s = np.linspace(0.0, path.length_m, 257)
    pts = path.evaluate(s)[0]
    np.testing.assert_allclose(np.linalg.norm(pts - centre, axis=1), radius, atol=1e-9)
    # planar: every point in the plane spanned by the start tangent and the bend normal
    axis = np.cross(FRAME0[:, 0], normal)
    np.testing.assert_allclose((pts - centre) @ axis, 0.0, atol=1e-9)


@settings(max_examples=15, deadline=None)
@given(st.floats(0.5, 3.0), st.floats(-4.0, 4.0).filter(lambda p: abs(p) > 0.05), unit_dir)
def test_helix_curvature_and_torsion_are_analytic(r, pitch, direction):
    c = pitch / (2 * np.pi)
    path = Path([helix_piece("h", r, pitch, 2 * np.pi, direction)], ORIGIN, FRAME0)
    assert path.length_m == pytest.approx(2 * np.pi * np.hypot(r, c))
    for s in np.linspace(0.1, path.length_m - 0.1, 7):
        p = path.point(s)
        assert p.curvature == pytest.approx(r / (r * r + c * c), rel=1e-6)
        assert p.torsion == pytest.approx(c / (r * r + c * c), rel=1e-6)
    # after one full turn the helix has risen by |pitch| along its axis, same tangent
    c0, F0 = path.evaluate(np.array([0.0]))[:2]
    c1, F1 = path.evaluate(np.array([path.length_m]))[:2]
    assert np.linalg.norm(c1 - c0) == pytest.approx(abs(pitch), rel=1e-6)
    np.testing.assert_allclose(F1[0][:, 0], F0[0][:, 0], atol=1e-7)


kvec = st.lists(st.floats(-2.0, 2.0), min_size=2, max_size=2).map(np.array)


@settings(deadline=None)      # pure numpy, but a loaded machine once took 0.93 s of the default 0.2 s
@given(st.floats(0.3, 5.0), kvec, kvec, kvec, kvec, kvec, kvec)
def test_blend_matches_value_slope_and_second_derivative_at_both_ends(L, a, b, c, d, e, f):
    bl = blend_piece("b", L, (a, b, c), (d, e, f))
    for got, want in zip(bl.start() + bl.end(), (a, b, c, d, e, f)):
        np.testing.assert_allclose(got, want, atol=1e-9)


def test_blend_derivatives_are_consistent():
    bl = blend_piece("b", 2.0, (np.zeros(2), np.zeros(2), np.zeros(2)),
                     (np.array([0.5, -0.2]), np.array([0.1, 0.0]), np.zeros(2)))
    s = np.linspace(0.01, 1.99, 50)
    h = 1e-6
    k, dk, ddk = bl.eval(s)
    np.testing.assert_allclose((bl.eval(s + h)[0] - bl.eval(s - h)[0]) / (2 * h), dk, atol=1e-7)
    np.testing.assert_allclose((bl.eval(s + h)[1] - bl.eval(s - h)[1]) / (2 * h), ddk, atol=1e-7)


MANEUVER = """\
kind: maneuver
version: 1
name: t
start: {{position_m: [0, 0, -3], heading_deg: 30}}
segments:
  - name: a
    line: {{length_m: 5.0}}
  - name: b
    {second}
  - name: c
    line: {{length_m: 5.0}}
    {blend}
speed: {{initial_m_s: 2.0}}
"""


def _spec(second, blend="blend_m: 2.0"):
    return load_maneuver_text(MANEUVER.format(second=second, blend=blend), "t.yaml")


@pytest.mark.parametrize("shape", ["arc: {radius_m: 2.0, angle_deg: 120, bend_deg: 90}\n    blend_m: 2.0",
                                   "helix: {radius_m: 2.0, pitch_m: 1.0, angle_deg: 300}\n    blend_m: 2.0"])
def test_blended_junctions_are_c2_on_the_built_path(shape):
    path = build_path(_spec(shape))
    kinds = [p.kind for p in path.pieces]
    assert kinds == ["line", "blend", kinds[2], "blend", "line"]
    for left, right in zip(path.pieces[:-1], path.pieces[1:]):
        for got, want in zip(left.end(), right.start()):
            np.testing.assert_allclose(got, want, atol=1e-9)
    # and on the tabulated path: curvature and its slope continuous across each blend end
    eps = 1e-7
    for span in path.spans[1:]:
        s0 = span.s_start_m
        k_l, dk_l = path.evaluate(np.array([s0 - eps]))[2:4]
        k_r, dk_r = path.evaluate(np.array([s0 + eps]))[2:4]
        np.testing.assert_allclose(k_l, k_r, atol=1e-5)
        np.testing.assert_allclose(dk_l, dk_r, atol=1e-4)


def test_unblended_curvature_jump_is_rejected_naming_the_junction():
    with pytest.raises(ManeuverError) as ei:
        build_path(_spec("arc: {radius_m: 2.0, angle_deg: 120}", blend=""))
    msg = str(ei.value)
    assert "junction 'a' -> 'b'" in msg and "s = 5.000 m" in msg
    assert "blend_m" in msg and "'b'" in msg


def test_waypoint_curve_passes_through_its_waypoints():
    pts = [[3.0, 1.0, 0.0], [6.0, 3.0, -1.0], [9.0, 3.0, -1.5]]
    spec = _spec(f"waypoints: {{points_m: {pts}}}", blend="")
    path = build_path(spec)
    span = next(sp for sp in path.spans if sp.name == "b")
    p0 = path.point(span.s_start_m).position
    s = np.arange(span.s_start_m, span.s_end_m, 2e-4)
    c = path.evaluate(s)[0]
    for q in pts:
        target = p0 + np.array(q)
        assert np.min(np.linalg.norm(c - target, axis=1)) < 1e-3
    # the curve joins the lines with zero curvature (no blend needed)
    assert np.linalg.norm(path.point(span.s_start_m).k) < 1e-6
    assert np.linalg.norm(path.point(span.s_end_m).k) < 1e-6
