"""Triangulated rigid tools, force-driven tools and the contact's travel bound (issue 8, deliverables 1-3, 7): the grid
query against brute force and an independent inside/outside test, a block on a triangulated plane against the
analytic plane, a blank holder pressing with a prescribed force, and the step bound that keeps a tool from carrying
a shell node through the surface in one cycle."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.physics.tools import triangulated

from helpers import run_data
from test_contact import G, balance, block

pytestmark = pytest.mark.verification


def l_prism():
    """A closed, outward-oriented L-shaped prism (a concave edge along z at (1, 1)): extruded from the L polygon
    (0,0) (2,0) (2,1) (1,1) (1,2) (0,2), z in [0, 1]; quads split into triangles."""
    poly = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], float)
    n = len(poly)
    P = np.vstack([np.column_stack([poly, np.zeros(n)]), np.column_stack([poly, np.ones(n)])])
    T = []
    for i in range(n):  # sides, counter-clockwise polygon: outward with (i, i+1, i+1+n)
        j = (i + 1) % n
        T += [[i, j, j + n], [i, j + n, i + n]]
    # caps: fan triangulation of the L from vertex 0 would cross the notch; use two convex parts
    for tri in ([0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]):
        T.append([tri[0], tri[2], tri[1]])  # bottom, normal -z
        T.append([t + n for t in tri])  # top, normal +z
    return P, np.array(T)


def winding_number(P, T, x):
    """Generalised winding number of a closed triangle surface about x (van Oosterom and Strackee solid angles):
    1 inside, 0 outside. Independent of the pseudonormals under test."""
    a, b, c = P[T[:, 0]] - x, P[T[:, 1]] - x, P[T[:, 2]] - x
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    num = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la \
        + np.einsum("ij,ij->i", c, a) * lb
    return float(np.sum(2 * np.arctan2(num, den)) / (4 * np.pi))


def brute_distance(P, T, x):
    """Unsigned distance to the closest of all triangles by enumeration, not by Voronoi regions: the distance to each
    triangle's plane where the foot of the perpendicular falls inside it (barycentric test), and to each of its three
    edges as clamped segments; the smallest of all."""
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    h = np.einsum("ij,ij->i", x - a, n)
    foot = x - h[:, None] * n
    # barycentric coordinates of the foot from the three sub-areas (all >= 0 inside)
    inside = np.ones(len(T), bool)
    for p0, p1 in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(p1 - p0, foot - p0), n) >= 0.0
    best = np.where(inside, np.abs(h), np.inf).min()
    for p0, p1 in ((a, b), (b, c), (c, a)):
        e = p1 - p0
        t = np.clip(np.einsum("ij,ij->i", x - p0, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
        best = min(best, float(np.linalg.norm(p0 + t[:, None] * e - x, axis=1).min()))
    return float(best)


def test_grid_query_matches_brute_force_and_winding_number_on_a_concave_solid():
    """Requirement: for 300 random points within the search radius of a concave closed surface, |d| equals the brute
    force distance over every triangle (1e-12 mm: both are exact, they differ by round-off) and the sign is
    minus inside / plus outside as given by the winding number (no tolerance: every point is at least 1e-3 from the
    surface); points beyond the search radius report d = r."""
    P, T = l_prism()
    r = 0.4
    surf = triangulated.build(P, T, r)
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 300:
        x = rng.uniform(-0.5, 2.5, 3)
        x[2] = rng.uniform(-0.5, 1.5)
        exact = brute_distance(P, T, x)
        if exact < 1e-3:
            continue
        d, n0, n1, n2 = triangulated.distance(*surf.arrays()[:-1], r, *x)
        if exact > r:
            assert d == r
            continue
        inside = winding_number(P, T, x) > 0.5
        assert abs(abs(d) - exact) < 1e-12
        assert (d < 0) == inside, (x, d)
        assert math.isclose(math.hypot(n0, n1, n2), 1.0, rel_tol=1e-12)
        checked += 1


def test_normal_is_the_distance_gradient():
    """Requirement: n = grad d by central differences (step 1e-6 mm, agreement 1e-6) at points near faces, edges
    and corners of the L prism, inside and out, away from the medial axis where d has a kink: the contact force p n
    is then -dE/dx."""
    P, T = l_prism()
    surf = triangulated.build(P, T, 0.5)
    args = surf.arrays()
    for x in ([1.5, 0.5, 1.2], [2.1, 1.1, 0.5], [1.1, 1.3, 0.5], [0.9, 0.9, 0.5], [2.2, -0.1, 1.1], [0.5, 0.5, 0.9]):
        x = np.array(x)
        d, *n = triangulated.distance(*args, *x)
        e = 1e-6
        g = [(triangulated.distance(*args, *(x + e * dx))[0] - triangulated.distance(*args, *(x - e * dx))[0])
             / (2 * e) for dx in np.eye(3)]
        assert np.allclose(g, n, atol=1e-6), (x, g, n)


def test_surface_file_problems_are_refused_by_name(tmp_path):
    """Requirement: a non-manifold or degenerate surface is a CompileError at tools.<name>.surface, not a blow-up."""
    import meshio

    from fdeck.compile.errors import CompileError

    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], float)
    meshio.write(tmp_path / "fan.stl", meshio.Mesh(P, [("triangle", np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))]))
    with pytest.raises(CompileError) as info:
        block([{"duration": 1e-4}], [], extra={"tools": {"floor": {"surface": {
            "shape": "mesh", "file": str(tmp_path / "fan.stl")}}}})
    ((path, message),) = info.value.problems
    assert path == ("tools", "floor", "surface") and "non-manifold" in message


def square(tmp_path, half=40.0, n=4):
    """An n x n grid of triangles covering [-half, half]^2 at z = 0, normals +z, written as STL."""
    import meshio

    s = np.linspace(-half, half, n + 1)
    X, Y = np.meshgrid(s, s, indexing="ij")
    P = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    T = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = i * (n + 1) + j, (i + 1) * (n + 1) + j, (i + 1) * (n + 1) + j + 1, i * (n + 1) + j + 1
            T += [[a, b, c], [a, c, d]]
    path = tmp_path / "floor.stl"
    meshio.write(path, meshio.Mesh(P, [("triangle", np.array(T))]), binary=True)
    return path


def test_block_on_a_triangulated_plane_runs_as_on_the_analytic_plane(tmp_path):
    """Requirement: a block settling and sliding with friction on a flat triangulated floor gives the same history
    as on the analytic plane: every column within 1e-9 of the largest value of its kind (a force component against
    the largest force component: a physically zero column holds round-off only; the two distances differ by
    round-off, binary STL storing float32 coordinates exact for these grid values)."""
    steps = [{"duration": 0.02, "damping": {"mass_proportional": 400.0}}, {"duration": 0.02}]
    loads = [{"type": "gravity", "acceleration": [0.4 * G, 0, -G]}]
    _, res_a, ha = block(steps, loads, friction={"static": 0.3})
    mesh_floor = {"floor": {"surface": {"shape": "mesh", "file": str(square(tmp_path))}}}
    _, res_m, hm = block(steps, loads, friction={"static": 0.3}, extra={"tools": mesh_floor})
    assert res_a.status == res_m.status == "completed"
    assert res_a.cycles == res_m.cycles
    _same_history(ha, hm)


def _same_history(ha, hm):
    """Every column of two histories within 1e-9 of the largest value of its kind (see the callers)."""
    for c in ha:
        family = [k for k in ha if k.rsplit("_", 1)[0] == c.rsplit("_", 1)[0]]  # force_x with force_y, force_z
        scale = max(max(np.abs(ha[k]).max() for k in family), 1e-30)
        if c in ("energy_balance_error", "contact_area_work"):  # round-off of energies (the area work is 0 on
            # the analytic plane, whose normal is exact, and round-off of the triangles' normals on the mesh)
            scale = max(np.abs(ha[k]).max() for k in ("kinetic_energy", "external_work", "friction_dissipation"))
        assert np.abs(ha[c] - hm[c]).max() <= 1e-9 * scale, c
    assert hm["friction_dissipation"][-1] > 0.0


def abaqus_floor(tmp_path, half=40.0, n=4):
    """An Abaqus .inp: the floor of ``square`` as n x n R3D4 facets (element set FLOOR, normals +z), and a second
    floor 0.5 mm higher of R3D3 facets (element set RAISED) that the block would start inside."""
    s = np.linspace(-half, half, n + 1)
    lines = ["*Heading", "rigid floors", "*Node"]
    ids = {}
    for i, x in enumerate(s):
        for j, y in enumerate(s):
            ids[i, j] = len(ids) + 1
            lines.append(f"{ids[i, j]}, {x}, {y}, 0.0")
    k = len(ids)
    for j, (x, y) in enumerate([(-half, -half), (half, -half), (half, half), (-half, half)]):
        lines.append(f"{k + j + 1}, {x}, {y}, 0.5")
    lines.append("*Element, type=R3D4, elset=FLOOR")
    e = 0
    for i in range(n):
        for j in range(n):
            e += 1
            lines.append(f"{e}, {ids[i, j]}, {ids[i + 1, j]}, {ids[i + 1, j + 1]}, {ids[i, j + 1]}")
    lines += ["*Element, type=R3D3, elset=RAISED", f"{e + 1}, {k + 1}, {k + 2}, {k + 3}",
              f"{e + 2}, {k + 1}, {k + 3}, {k + 4}"]
    path = tmp_path / "floors.inp"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_block_on_an_abaqus_r3d4_floor_runs_as_on_the_analytic_plane(tmp_path):
    """Requirement: a tool read from an Abaqus .inp of R3D4 facets (which meshio's reader does not know: read as
    quads) and restricted to its element set by ``part`` gives the history of the analytic plane, as the STL floor
    does (every column within 1e-9 of the largest of its kind); the file's other set, a floor 0.5 mm higher, is left
    out: chosen alone, the block's 9 bottom nodes start 0.5 mm inside it (refused, naming them)."""
    from fdeck.compile.errors import CompileError

    steps = [{"duration": 0.02, "damping": {"mass_proportional": 400.0}}, {"duration": 0.02}]
    loads = [{"type": "gravity", "acceleration": [0.4 * G, 0, -G]}]
    path = abaqus_floor(tmp_path)
    P, T = triangulated.read(path, "FLOOR")
    assert len(T) == 32 and np.all(P[:, 2] == 0.0)  # 16 R3D4 facets, two triangles each
    assert np.all(np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])[:, 2] > 0.0)  # normals +z
    _, res_a, ha = block(steps, loads, friction={"static": 0.3})
    floor = {"floor": {"surface": {"shape": "mesh", "file": str(path), "part": "FLOOR"}}}
    _, res_m, hm = block(steps, loads, friction={"static": 0.3}, extra={"tools": floor})
    assert res_a.status == res_m.status == "completed" and res_a.cycles == res_m.cycles
    _same_history(ha, hm)
    assert len(triangulated.read(path)[1]) == 34  # without ``part``: both sets
    raised = {"floor": {"surface": {"shape": "mesh", "file": str(path), "part": "RAISED"}}}
    with pytest.raises(CompileError, match="9 blank nodes start inside tool 'floor'"):
        block(steps, loads, friction={"static": 0.3}, extra={"tools": raised})


def test_blank_holder_driven_by_a_force_presses_with_that_force(tmp_path):
    """Requirement: a plane holder of mass M driven down by F = 50 N onto a linear-elastic block resting on a fixed
    floor (frictionless, damped to rest) settles where the block carries F: the floor's force is F within 1 %, and
    the holder's travel is F L / (E A) (the block's uniaxial shortening, nu free to act laterally) plus the two
    penalty overclosures F / (k A), within 1 % (the block's lateral bulge under 1 % strain changes A by 0.3 % and
    the damped rest leaves far less)."""
    F, k, E, A, L = 50.0, 2000.0, 1000.0, 100.0, 5.0
    holder = {"holder": {"surface": {"shape": "plane", "point": [0, 0, 5.0], "normal": [0, 0, -1]},
                         "motion": {"kind": "force", "value": F, "mass": 1e-4}}}
    contact = [{"tool": "floor", "normal": {"law": "linear", "stiffness": k}},
               {"tool": "holder", "normal": {"law": "linear", "stiffness": k}}]
    extra = {"tools": {"floor": {"surface": {"shape": "plane"}}, **holder}, "contact": contact}
    _, res, h = block([{"duration": 0.06, "damping": {"mass_proportional": 600.0}}], [], stiffness=k, extra=extra)
    assert res.status == "completed", res.message
    assert -h["tool_floor_force_z"][-1] == pytest.approx(-F, rel=0.01) or \
        h["tool_floor_force_z"][-1] == pytest.approx(F, rel=0.01)
    travel = F * L / (E * A) + 2 * F / (k * A)
    assert -h["tool_holder_displacement_z"][-1] == pytest.approx(travel, rel=0.01)
    assert balance(h) < 0.01


def test_a_fast_tool_sub_steps_the_run_rather_than_pass_through_a_shell():
    """Requirement: a plane moving at 2e4 mm/s toward a 0.23 mm shell bounds the step so that it travels at most
    half the shell's half-thickness a cycle (0.0575 mm -> dt <= 2.875e-6 s, checked exactly on the run's largest
    step), and the plate ends on the tool's side it started on (pushed, not passed through)."""
    v = 2.0e4
    data = {
        "mesh": {"plate": {"size": [20.0, 20.0], "divisions": [4, 4]}},
        "materials": {"fab": {"type": "sm"}},
        "sections": [{"material": "fab"}],
        "tools": {"pusher": {"surface": {"shape": "plane", "point": [0, 0, 1.0], "normal": [0, 0, -1]},
                             "motion": {"kind": "velocity", "value": v}}},
        "contact": [{"tool": "pusher", "normal": {"law": "linear", "stiffness": 50.0}}],
        "steps": [{"duration": 1.5e-4}],
        "output": {"measures": [{"type": "node_displacement", "name": "uz", "nodes": "all", "component": "z"}]},
    }
    problem, res, h = run_data(data)
    assert res.status == "completed", res.message
    assert res.dt_max <= 0.5 * 0.115 / v * (1 + 1e-12)
    travel = v * 1.5e-4  # 3 mm: the plane passes z = 0 at 0.5e-4 s and pushes the plate 2 mm down
    assert h["uz"][-1] < -(travel - 1.0) * 0.9


def test_a_point_behind_an_open_sheet_rim_is_not_pushed_through_the_face():
    """Requirement: for an open sheet (a 2 x 2 square, normals +z), a point under its face is inside (d = -depth,
    exact) and so is a point straight under a rim edge, while a point that went round its rim (closest to a rim edge
    or corner, below the sheet and beyond it) is far (d = r):
    pushing it back through the face would create energy (a blank bulging over a holder's opening edge)."""
    P = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)
    T = np.array([[0, 1, 2], [0, 2, 3]])
    r = 0.5
    args = triangulated.build(P, T, r).arrays()
    assert triangulated.distance(*args, 1.0, 0.7, -0.1)[0] == pytest.approx(-0.1, abs=1e-15)
    assert triangulated.distance(*args, 1.0, 0.7, 0.2)[0] == pytest.approx(0.2, abs=1e-15)
    assert triangulated.distance(*args, 2.1, 1.0, -0.05)[0] == r  # beyond the x = 2 rim edge, below
    assert triangulated.distance(*args, -0.1, -0.1, -0.05)[0] == r  # beyond the corner, below
    assert triangulated.distance(*args, 2.1, 1.0, 0.05)[0] == pytest.approx(math.hypot(0.1, 0.05), abs=1e-15)
    # straight under the rim (a node on the symmetry plane of a quarter model under a quarter tool's open side):
    # penetrated, not gone round
    assert triangulated.distance(*args, 2.0, 1.0, -0.05)[0] == pytest.approx(-0.05, abs=1e-15)
