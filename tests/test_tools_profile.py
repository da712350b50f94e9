"""The extruded rounded profile tool (issue 8, deliverable 1: "extruded rounded profile"): its fillets against their
tangency conditions, its signed distance against brute force and an independent inside test, its normal against
the distance's gradient, its drawn facets on the surface, a block on its flat part against the analytic plane, and
fillets that do not fit refused where they are written."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.cards.contact import Profile
from fdeck.physics.tools import analytic, profile

from test_contact import G, block
from test_tools_triangulated import _same_history

pytestmark = pytest.mark.verification

# a channel 40 mm wide and 30 mm deep between two flanges, in the x-z plane, extruded along -y (u = x, v = z)
CHANNEL = [(-60.0, 0.0), (-20.0, 0.0), (-20.0, -30.0), (20.0, -30.0), (20.0, 0.0), (60.0, 0.0)]
RADII = [5.0, 8.0, 8.0, 5.0]


def channel() -> tuple[int, np.ndarray]:
    card = Profile(shape="profile", points=CHANNEL, radii=RADII, u_axis=(1, 0, 0), v_axis=(0, 0, 1))
    return analytic.pack(card)


def _line_distance(q, a, b):
    """Signed distance of 2-D point q from the infinite line a -> b (positive on its left)."""
    t = (b - a) / np.linalg.norm(b - a)
    return t[0] * (q[1] - a[1]) - t[1] * (q[0] - a[0])


def test_fillets_are_tangent_to_both_segments_and_join_them():
    """Requirement: each fillet's centre lies r from both corner segments' lines, on the inner side of the turn
    (left of the walk for a left turn), and the pieces join end to end: every segment's end is its fillet's
    tangent point (r from the centre, 1e-12 mm) and lies on the original polyline segment (1e-12 mm)."""
    parts = profile.pieces(CHANNEL, RADII)
    assert [p[0] for p in parts] == ["line", "arc"] * 4 + ["line"]
    P = np.array(CHANNEL)
    for k in range(4):
        _, c, r, turn, _, _ = parts[2 * k + 1]
        for a, b in ((P[k], P[k + 1]), (P[k + 1], P[k + 2])):
            assert _line_distance(c, a, b) == pytest.approx(turn * r, abs=1e-12)
        before, after = parts[2 * k][2], parts[2 * k + 2][1]
        assert np.linalg.norm(before - c) == pytest.approx(r, abs=1e-12)
        assert np.linalg.norm(after - c) == pytest.approx(r, abs=1e-12)
        assert abs(_line_distance(before, P[k], P[k + 1])) < 1e-12
        assert abs(_line_distance(after, P[k + 1], P[k + 2])) < 1e-12


def _samples(parts, h=0.002):
    """Points along every piece about h mm apart (open ends continued 40 mm), from the pieces' own data."""
    out = []
    for p in parts:
        if p[0] == "line":
            a, b = p[1].copy(), p[2].copy()
            t = (b - a) / np.linalg.norm(b - a)
            a, b = a - 40.0 * t * p[3], b + 40.0 * t * p[4]
            n = int(np.linalg.norm(b - a) / h) + 2
            out.append(a + np.linspace(0, 1, n)[:, None] * (b - a))
        else:
            c, r, _, mid, cos_half = p[1:]
            base, half = math.atan2(mid[1], mid[0]), math.acos(cos_half)
            ang = np.linspace(base - half, base + half, int(2 * half * r / h) + 2)
            out.append(c + r * np.column_stack([np.cos(ang), np.sin(ang)]))
    return np.concatenate(out)


def test_signed_distance_matches_brute_force_and_a_point_in_polygon_test():
    """Requirement: at 3 000 random points within 25 mm of the channel, |d| equals the distance to the nearest of
    the profile's densely sampled points (h = 2 um apart), within 1e-5 mm for the points farther than 0.1 mm from
    the surface (the sampling error, sqrt(d^2 + (h/2)^2) - d <= h^2 / (8 d), is 5e-9 mm there; nearer points can be
    off by up to h/2), and the sign is that of an independent test: inside the tool (d < 0) exactly where a
    ray-casting point-in-polygon test puts the point in the polygon that closes the sampled profile 100 mm below it
    (points within 1e-6 mm of the surface skipped)."""
    from matplotlib.path import Path

    kind, p = channel()
    curve = _samples(profile.pieces(CHANNEL, RADII))
    closed = np.vstack([curve, [[curve[-1, 0], -130.0], [curve[0, 0], -130.0]]])
    rng = np.random.default_rng(7)
    q = np.column_stack([rng.uniform(-70, 70, 3000), rng.uniform(-55, 25, 3000)])
    d = np.array([analytic.distance(kind, p, x, 3.0, z)[0] for x, z in q])
    from scipy.spatial import cKDTree

    brute, _ = cKDTree(curve).query(q)
    near = (brute < 25.0) & (brute > 0.1)
    assert near.sum() > 2000
    np.testing.assert_allclose(np.abs(d[near]), brute[near], atol=1e-5)
    inside = Path(closed).contains_points(q)
    sure = (brute < 25.0) & (brute > 1e-6)
    np.testing.assert_array_equal(d[sure] < 0.0, inside[sure])


def test_normal_is_the_distance_gradient():
    """Requirement: the returned normal is the unit gradient of the signed distance (central differences with
    h = 1e-6 mm, 1e-6) at 300 random points within 4 mm of the surface (closer than any fillet radius, so off the
    medial axis), the component along the extrusion axis zero; the penalty force p n is then -dE/dx."""
    kind, p = channel()
    rng = np.random.default_rng(3)
    checked = 0
    while checked < 300:
        x = np.array([rng.uniform(-70, 70), rng.uniform(-5, 5), rng.uniform(-40, 10)])
        d, *n = analytic.distance(kind, p, *x)
        if abs(d) > 4.0:
            continue
        grad = np.array([(analytic.distance(kind, p, *(x + e))[0] - analytic.distance(kind, p, *(x - e))[0]) / 2e-6
                         for e in 1e-6 * np.eye(3)])
        np.testing.assert_allclose(n, grad, atol=1e-6)
        assert abs(np.linalg.norm(n) - 1.0) < 1e-12 and n[1] == 0.0
        checked += 1


def test_drawn_facets_lie_on_the_surface_and_face_the_blank():
    """Requirement: the facets written to the frames have every point on the surface (|d| < 1e-9 mm: the points are
    the profile's own, the arcs sampled on their circles) and every triangle's right-hand normal on the blank's side
    (its dot product with the distance's normal at the centroid, projected back to the surface, above 0.9: a chord
    of 1/8 of a 90 degree fillet turns the normal by at most 6 degrees)."""
    kind, p = channel()
    P, T = analytic.facets(kind, p, np.array([-50.0, -10.0, -1.0, 50.0, 10.0, 1.0]))
    assert max(abs(analytic.distance(kind, p, *x)[0]) for x in P) < 1e-9
    tri = P[T]
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    for c, m in zip(tri.mean(axis=1), nrm):
        d, *n = analytic.distance(kind, p, *c)
        assert float(np.dot(m, n)) > 0.9


def test_block_on_the_profile_flange_runs_as_on_the_analytic_plane():
    """Requirement: the 10 x 10 mm block settling and sliding with friction on a profile's flat flange, away from its
    fillets, has the history of the same run on the analytic plane z = 0 to round-off, as the triangulated floor
    does (1e-9 of the largest value of each column's kind: on a flat piece the profile's distance differs from the
    plane's in the last bits, which 3 000 cycles of a stick-slip history amplify to about 1e-11)."""
    steps = [{"duration": 0.02, "damping": {"mass_proportional": 400.0}}, {"duration": 0.02}]
    loads = [{"type": "gravity", "acceleration": [0.4 * G, 0, -G]}]
    _, res_a, ha = block(steps, loads, friction={"static": 0.3})
    flange = {"floor": {"surface": {"shape": "profile", "points": [[-100, 0], [40, 0], [40, -20], [60, -20]],
                                    "radii": 5.0}}}
    _, res_p, hp = block(steps, loads, friction={"static": 0.3}, extra={"tools": flange})
    assert res_a.status == res_p.status == "completed" and res_a.cycles == res_p.cycles
    _same_history(ha, hp)


def test_fillets_that_do_not_fit_are_refused_where_they_are_written():
    """Requirement: a profile whose fillets need more of a segment than it has, or that crosses itself (its open
    ends continued), is a located compile error at the tool's surface naming the segments; a radius list of the
    wrong length, a zero radius and parallel axes are deck errors at the surface."""
    from fdeck.compile.errors import CompileError
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    def deck(surface):
        return {"mesh": {"block": {"origin": [0, 0, 1], "size": [1, 1, 1], "divisions": [1, 1, 1]}},
                "materials": {"m": {"type": "linear_elastic", "density": 1e-6, "youngs_modulus": 1000.0,
                                    "poisson_ratio": 0.3}},
                "sections": [{"material": "m"}], "tools": {"die": {"surface": surface}},
                "contact": [{"tool": "die", "normal": {"law": "linear", "stiffness": 100.0}}],
                "steps": [{"duration": 1e-3}]}

    tight = {"shape": "profile", "points": [[-50, 0], [0, 0], [0, -10], [50, -10]], "radii": 8.0}
    with pytest.raises(CompileError) as info:
        compile_deck(Deck.model_validate(deck(tight)))
    ((path, message),) = info.value.problems
    assert path == ("tools", "die", "surface") and "segment 2 (points 2-3) need 16 mm of its 10 mm" in message
    crossed = {"shape": "profile", "points": [[0, 0], [10, 0], [10, 10], [5, -5]], "radii": 1.0}
    with pytest.raises(CompileError) as info:
        compile_deck(Deck.model_validate(deck(crossed)))
    ((path, message),) = info.value.problems
    assert path == ("tools", "die", "surface") and "crosses itself: segments 1 and 3" in message
    for bad, words in (({"radii": [1.0]}, "lists 1 values for 2 interior points"), ({"radii": 0.0}, "> 0"),
                       ({"v_axis": [2, 0, 0]}, "must not be parallel")):
        with pytest.raises(Exception, match=words):
            Deck.model_validate(deck({**tight, **bad}))


def test_a_ridge_of_two_meeting_fillets_is_a_half_cylinder_on_two_walls():
    """Requirement: fillets that take a segment whole leave no line piece (the arcs meet, tangent), and an end
    segment taken whole keeps its direction. A ridge walked up x = -10, across z = 0 and down x = 10 with radius 10
    is a half cylinder of radius 10 about (0, -10) on two vertical walls: at 2 000 random points the signed distance
    is |q - c| - 10 above z = -10 and |x| - 10 below, the closed forms, within 1e-9 mm (including the top's common
    radius x = 0, where the two arcs meet); a corner whose fillet takes the whole first segment leaves the open start
    along that segment's line (distance = z beyond it)."""
    card = Profile(shape="profile", points=[(-10, -30), (-10, 0), (10, 0), (10, -30)], radii=10.0)
    assert [q[0] for q in profile.pieces(card.points, card.radii)] == ["line", "arc", "arc", "line"]
    kind, p = analytic.pack(card)
    rng = np.random.default_rng(11)
    pts = np.column_stack([rng.uniform(-25, 25, 2000), rng.uniform(-3, 3, 2000), rng.uniform(-40, 15, 2000)])
    pts[:20, 0] = 0.0  # on the common radius of the two arcs
    for x, y, z in pts:
        expected = math.hypot(x, z + 10.0) - 10.0 if z >= -10.0 else abs(x) - 10.0
        assert analytic.distance(kind, p, x, y, z)[0] == pytest.approx(expected, abs=1e-9), (x, z)
    kind, p = analytic.pack(Profile(shape="profile", points=[(-5, 0), (0, 0), (0, -20)], radii=5.0))
    assert [q[0] for q in profile.pieces([(-5, 0), (0, 0), (0, -20)], 5.0)] == ["line", "arc", "line"]
    assert analytic.distance(kind, p, -20.0, 0.0, 3.0)[0] == pytest.approx(3.0, abs=1e-12)


def test_points_on_a_flat_piece_get_its_own_normal():
    """Requirement: a point on or next to a straight piece, or on an open end's continuation, gets that piece's left
    normal exactly and its signed distance along it (1e-12), whatever the round-off of the foot along the line: a
    blank node placed on a die face must not be pushed sideways. On the channel's flange (z = 0, x = -27.88), on a
    30 degree slope of a two-point profile (no fillets), and 1e-12 mm off it."""
    kind, p = channel()
    d, *n = analytic.distance(kind, p, -27.88, 0.0, 0.0)
    assert abs(d) < 1e-12 and n == [0.0, 0.0, 1.0]
    a = math.radians(30.0)
    kind, p = analytic.pack(Profile(shape="profile", points=[(0, 0), (10, 10 * math.tan(a))]))
    for off in (0.0, 1e-12):
        d, *n = analytic.distance(kind, p, 5.0 - off * math.sin(a), 0.0, 5.0 * math.tan(a) + off * math.cos(a))
        assert d == pytest.approx(off, abs=1e-12)
        np.testing.assert_allclose(n, [-math.sin(a), 0.0, math.cos(a)], atol=1e-12)
    d, *n = analytic.distance(kind, p, -20.0, 0.0, -20.0 * math.tan(a) + 1.0)  # beyond the open start
    assert d == pytest.approx(math.cos(a), abs=1e-12)
