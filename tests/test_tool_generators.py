"""Parametric rigid-tool surfaces (fdeck.physics.tools.generators): orientation, closure, dimensions, radii, files."""

import numpy as np
import pytest

from fdeck.physics.tools import generators as g

CASES = {
    "dd_punch": (g.double_dome, dict(part="punch")),
    "dd_punch_full": (g.double_dome, dict(part="punch", quarter=False, h=4.0)),
    "dd_die": (g.double_dome, dict(part="die")),
    "dd_holder": (g.double_dome, dict(part="holder")),
    "tube_lower": (g.square_tube, dict(part="lower")),
    "tube_upper": (g.square_tube, dict(part="upper")),
}
CLOSED = {"dd_punch", "dd_punch_full", "tube_lower"}


def _mesh(name):
    f, kw = CASES[name]
    return f(**kw)


def _edges(tri):
    e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    return e


def _normals(p, t):
    return np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])


@pytest.mark.parametrize("name", list(CASES))
def test_conforming_no_degenerate_no_duplicates(name):
    """Requirement: every edge is shared by at most two triangles, interior edges by exactly two with opposite
    orientation (closed solids: every edge), no zero-area or duplicate triangle. Exact integer checks; area
    threshold 1e-6 mm^2, far below any facet (h^2 / 2 >= 4 mm^2)."""
    p, t = _mesh(name)
    assert (np.linalg.norm(_normals(p, t), axis=1) > 1e-6).all()
    assert len(np.unique(np.sort(t, axis=1), axis=0)) == len(t)
    e = _edges(t)
    directed, cnt = np.unique(e, axis=0, return_counts=True)
    assert cnt.max() == 1                       # a directed edge used twice = inconsistent orientation
    und, ucnt = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    assert ucnt.max() <= 2
    if name in CLOSED:
        assert (ucnt == 2).all()                # watertight
    # an edge used twice appears once in each direction (opposite orientation), checked by cnt.max() == 1


def _gauss_volume_punch(quarter, hq=0.25):
    """Reference: integral of (z_back - z(x, y)) over the plan by the midpoint rule on a grid 16x finer."""
    p = g.double_dome_params()
    xs = np.arange(hq / 2, p["rho_c"], hq)
    ys = np.arange(hq / 2, 235.0, hq)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    z = g.double_dome_surface(X, Y, off=2.6)
    z_back = 40.0 + 2.6                         # the punch's back: 40 mm above its highest face point (flange + c)
    v = float((z_back - z).sum() * hq * hq)
    return v if quarter else 4 * v


@pytest.mark.parametrize("name,quarter,h", [("dd_punch", True, 4.0), ("dd_punch_full", False, 4.0)])
def test_punch_volume_divergence_theorem(name, quarter, h):
    """Requirement: the closed double-dome punch's signed volume (divergence theorem) is positive (normals point
    out) and equals the integral of its analytic height field within the faceting error. Bound: on a triangle of
    diameter d the linear interpolant of z differs from z by at most M d^2 / 2 (Taylor with remainder at the
    vertices, barycentric weights sum to 1), M the largest second derivative of z: on the entry torus (tube
    r = 10 + 2.6 mm, slopes up to asin(rho_t / R)) M = 1 / (r cos^3), on the saddle blend (slopes +-0.72,
    width 20 mm) M = 1.44^2 / 40; so |dV| <= A M d^2 / 2 with d = h sqrt(2). The reference quadrature's own error
    (midpoint rule, 0.25 mm) is below 1e-3 of that bound."""
    p, t = _mesh(name)
    v = g.signed_volume(p, t)
    ref = _gauss_volume_punch(quarter)
    prm = g.double_dome_params()
    cos = np.sqrt(1 - (prm["rho_t"] / prm["R"]) ** 2)
    M = max(1.0 / (12.6 * cos ** 3), 1.44 ** 2 / 40.0)
    area = 135.0 * 235.0 * (1 if quarter else 4)
    bound = area * M * (2 * h * h) / 2
    assert v > 0
    assert abs(v - ref) <= bound, (v, ref, bound)


@pytest.mark.parametrize("name,side", [("dd_die", +1), ("dd_holder", -1), ("tube_upper", -1)])
def test_open_sheet_normals_face_the_blank(name, side):
    """Requirement: open sheets are oriented toward the blank: the die's normals have a positive z component,
    the holder's and the upper tool's a negative one (each face is a height field, so the sign is strict; the
    1e-9 margin only excludes round-off)."""
    p, t = _mesh(name)
    n = _normals(p, t)
    assert (side * n[:, 2] > 1e-9).all()


def test_closed_lower_tool_orientation():
    """Requirement: the square-tube lower tool is closed and oriented outward: positive signed volume, its top
    face normals point up; volume bounded by the sharp-edged block + base: 0 < V < 160^2 * 45 (box of the
    quarter model)."""
    p, t = _mesh("tube_lower")
    v = g.signed_volume(p, t)
    assert 0 < v < 160.0 ** 2 * 45.0
    c = p[t].mean(axis=1)
    top = c[:, 2] > -1e-9
    assert (_normals(p, t)[top, 2] > 0).all()


def test_key_dimensions():
    """Requirement: bounding boxes equal the set-up's dimensions (exact to round-off, 1e-9 mm): die cavity
    depth 60 mm and flange at z = 0, punch plan 135 x 235 (quarter of 270 x 470) and lowest point -60 + c
    (closed position), holder at z = 2.54, square-tube block top at 0, foot at -25 mm."""
    p, _ = _mesh("dd_die")
    assert abs(p[:, 2].min() + 60.0) < 1e-9 and abs(p[:, 2].max()) < 1e-9
    p, _ = _mesh("dd_punch")
    assert np.allclose(p[:, :2].max(axis=0), [135.0, 235.0], atol=1e-9)
    assert abs(p[:, 2].min() - (-60.0 + 2.6)) < 1e-9
    p, _ = _mesh("dd_holder")
    assert np.allclose(p[:, 2], 2.54)
    p, _ = _mesh("tube_upper")
    assert abs(p[:, 2].max() - 0.3) < 1e-9 and abs(p[:, 2].min() - (-25.0 + 0.3)) < 1e-9
    p, t = _mesh("tube_lower")
    face = p[np.abs(p[:, 0] - 160.0) > 1e-9]
    assert abs(face[:, 2].max()) < 1e-9


def test_fillet_radii():
    """Requirement: vertices on a fillet lie at its radius from its centre (exact placement, 1e-9 relative), and
    edge midpoints on the double-dome lobe sphere lie inside it by at most the chord sagitta R - sqrt(R^2 - e^2 / 4) ~ e^2 / (8 R)."""
    prm = g.double_dome_params()
    p, t = _mesh("dd_die")
    # lobe 1 (centre (0, yc, zc)), vertices of the spherical part far from the saddle blend
    rho = np.hypot(p[:, 0], p[:, 1] - prm["yc"])
    on_sph = (rho < prm["rho_t"] - 1e-6) & (p[:, 1] > prm["yc"])
    d = np.linalg.norm(p[on_sph] - [0.0, prm["yc"], prm["zc"]], axis=1)
    assert on_sph.sum() > 50 and np.allclose(d, prm["R"], rtol=1e-9)
    # entry torus: distance to the tube's centre circle (plan radius rho_c, z = -r) equals r
    on_tor = (rho > prm["rho_t"] + 1e-6) & (rho < prm["rho_c"] - 1e-6) & (p[:, 1] > prm["yc"])
    dt = np.hypot(rho[on_tor] - prm["rho_c"], p[on_tor, 2] + prm["r"])
    assert on_tor.sum() > 10 and np.allclose(dt, prm["r"], rtol=1e-9)
    # chord error: midpoints of edges with both ends on the sphere
    e = _edges(t)
    both = on_sph[e].all(axis=1)
    m = 0.5 * (p[e[both, 0]] + p[e[both, 1]])
    L = np.linalg.norm(p[e[both, 0]] - p[e[both, 1]], axis=1)
    gap = prm["R"] - np.linalg.norm(m - [0.0, prm["yc"], prm["zc"]], axis=1)
    sag = prm["R"] - np.sqrt(prm["R"] ** 2 - L ** 2 / 4)     # sagitta of a chord L, ~ L^2 / (8 R)
    assert (gap >= -1e-9).all() and (gap <= sag + 1e-9).all()
    # square tube: top edge fillet (r_top = 5) centres lie 5 mm inside the straight side at x = 50 - T ... use
    # the straight side y < 40: fillet centre (50 - T, -5) in the (x, z) plane
    p, _ = _mesh("tube_lower")
    T = 5.0 * np.tan(np.radians(40.0))
    sel = (p[:, 1] < 35.0) & (p[:, 0] > 50.0 - T + 1e-6) & (p[:, 0] < 50.0 - T + 5.0 * np.sin(np.radians(80)) - 1e-6)
    sel &= p[:, 2] > -5.0
    dt = np.hypot(p[sel, 0] - (50.0 - T), p[sel, 2] + 5.0)
    assert sel.sum() > 5 and np.allclose(dt, 5.0, rtol=1e-9)


@pytest.mark.parametrize("suffix", [".stl", ".obj"])
def test_round_trip_meshio(tmp_path, suffix):
    """Requirement: write_surface output reads back through meshio with the same triangles (STL float32:
    coordinates within 1e-4 mm for |x| < 400 mm; OBJ text: within 1e-6)."""
    import meshio

    p, t = _mesh("dd_punch")
    f = tmp_path / f"punch{suffix}"
    g.write_surface(f, p, t)
    m = meshio.read(f)
    q, s = m.points, m.cells_dict["triangle"]
    assert len(s) == len(t)
    assert np.allclose(np.sort(q[s].reshape(-1, 9), axis=0), np.sort(p[t].reshape(-1, 9), axis=0),
                       atol=1e-4 if suffix == ".stl" else 1e-6)


# ---------------------------------------------------------------------------------------------------------------
# tetrahedral punch
# ---------------------------------------------------------------------------------------------------------------
R_T = 10.0


@pytest.fixture(scope="module")
def tetra():
    return g.tetrahedron(part="punch"), g.tetrahedron(part="die")


def _tetra_exact_volume(xs_span, ys_span, back=30.0):
    """Half punch volume: plate (plan rectangle x back) + half of the rounded tetrahedron below its top plane.
    Rounded body (Steiner): V + S r + r^2 sum_e L_e beta_e / 2 + 4/3 pi r^3 (beta_e: angle between the outward
    normals of the faces at edge e); the part above the top plane: A_top r + perimeter pi r^2 / 4 (quarter
    cylinders outside the top face's prism) + 2/3 pi r^3 (vertex wedges, exterior angles summing to 2 pi)."""
    v, faces = g.tetra_core(apex_z=-60.0 + R_T)
    n = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    area = np.linalg.norm(n, axis=1) / 2
    nu = n / (2 * area[:, None])
    edges = {}
    for fi, f in enumerate(faces):
        for k in range(3):
            edges.setdefault(tuple(sorted((f[k], f[(k + 1) % 3]))), []).append(fi)
    mean_w = sum(np.linalg.norm(v[a] - v[b]) * np.arccos(np.clip(nu[f1] @ nu[f2], -1, 1)) / 2
                 for (a, b), (f1, f2) in edges.items())
    vol = abs(np.linalg.det(v[1:] - v[0])) / 6
    total = vol + area.sum() * R_T + mean_w * R_T ** 2 + 4 / 3 * np.pi * R_T ** 3
    above = area[3] * R_T + 3 * 265.0 * np.pi * R_T ** 2 / 4 + 2 / 3 * np.pi * R_T ** 3
    return xs_span * ys_span * back + (total - above) / 2


def test_tetra_punch_closed_and_volume(tetra):
    """Requirement: the tetrahedral punch (half model) is watertight, oriented outward and its divergence-theorem
    volume equals the exact volume (Steiner formula of the rounded tetrahedron, see _tetra_exact_volume) within the
    faceting bound: per triangle |I z - z| <= M d^2 / 2 (Taylor at the vertices) with M = 1 / (r cos^3 57.5 deg)
    where the face slopes at most 57.5 deg (lateral faces, edge cylinders between them, apex sphere); 0 on flat
    triangles (all vertices on one lateral face's offset plane, or on the plate clear of the footprint); and
    r + 1.6 d in the steep band under the top edges (z > plate - r), where z and its interpolant both lie in
    [min - 1.57 d, plate]."""
    (p, t), _ = tetra
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, cnt = np.unique(e, axis=0, return_counts=True)
    assert (cnt == 2).all()
    v, faces = g.tetra_core(apex_z=-60.0 + R_T)
    z_plate = v[1, 2]
    face = p[:, 2] < z_plate + 1.0                         # the forming face (the back lid is 30 mm up)
    # vertex on a lateral face's flat offset: plane distance r and projection inside that face
    flat_id = np.full(len(p), -1)
    for i, f in enumerate(faces[:3]):
        a, b, c = v[f]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        q = p - np.outer((p - a) @ n - R_T, n) - R_T * n
        on = np.abs((p - a) @ n - R_T) < 1e-7
        bary = np.linalg.lstsq(np.column_stack([b - a, c - a]), (q - a).T, rcond=None)[0].T
        on &= (bary.min(axis=1) > 0) & (bary.sum(axis=1) < 1)
        flat_id[on & face] = i
    inr_top = 265.0 / (2 * np.sqrt(3.0))
    clear = (g._triangle_sd(p[:, 0], p[:, 1], inr_top) - R_T > 0) & (np.abs(p[:, 2] - z_plate) < 1e-9)
    tri_face = face[t].all(axis=1)
    T = t[tri_face]
    d = np.max([np.linalg.norm(p[T[:, i]] - p[T[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=0)
    u, w = p[T[:, 1], :2] - p[T[:, 0], :2], p[T[:, 2], :2] - p[T[:, 0], :2]
    a_plan = 0.5 * np.abs(u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0])
    flat = ((flat_id[T] >= 0).all(axis=1) & (flat_id[T] == flat_id[T[:, :1]]).all(axis=1)) | clear[T].all(axis=1)
    band = (p[T, 2] > z_plate - R_T).any(axis=1) & ~flat
    M = 1.0 / (R_T * np.cos(np.radians(57.5)) ** 3)
    b = np.where(flat, 0.0, np.where(band, R_T + 1.6 * d, M * d * d / 2))
    bound = float((a_plan * b).sum())
    exact = _tetra_exact_volume(np.ptp(p[:, 0]), np.ptp(p[:, 1]))
    vol = g.signed_volume(p, t)
    assert vol > 0 and abs(vol - exact) <= bound, (vol, exact, bound)
    assert bound < 0.1 * exact                             # the bound itself is informative (< 10 %)


def test_tetra_rounded_edges_and_apex(tetra):
    """Requirement: the punch face lies on the rounded tetrahedron: no vertex beyond r of any face plane (1e-7 mm,
    the bisection resolves 2^-60 of 200 mm), the lowest vertex is the apex sphere's bottom (apex_z - r), and
    vertices near the lateral edges (not on a flat face, away from apex and top) lie at distance r from the edge
    segment (edge fillet radius, 1e-7 mm)."""
    (p, t), _ = tetra
    v, faces = g.tetra_core(apex_z=-60.0 + R_T)
    z_plate = v[1, 2]
    face = p[p[:, 2] < z_plate - 1e-6]
    dmax = []
    for f in faces[:3]:
        a, b, c = v[f]
        n = np.cross(b - a, c - a)
        dmax.append((face - a) @ (n / np.linalg.norm(n)))
    dmax = np.max(dmax, axis=0)
    assert (dmax <= R_T + 1e-7).all()
    assert abs(p[:, 2].min() - (-60.0)) < 1e-7
    # lateral edges apex -> top vertex k: distance to the segment
    sel = (dmax < R_T - 1e-3) & (face[:, 2] < z_plate - 2 * R_T) & (np.hypot(face[:, 0], face[:, 1]) > 3 * R_T)
    dist = []
    for k in (1, 2, 3):
        a, b = v[0], v[k]
        s = np.clip((face - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
        dist.append(np.linalg.norm(face - (a + s[:, None] * (b - a)), axis=1))
    dist = np.min(dist, axis=0)
    assert sel.sum() > 10 and np.allclose(dist[sel], R_T, atol=1e-7)


def test_tetra_open_die(tetra):
    """Requirement: the open die is an oriented sheet with a hole: normals up (strict), conforming (each edge in at
    most two triangles, never twice in one direction), boundary = outer border + the opening's rim, flange at z = 0,
    and its entry edge lies on the entry-radius fillet: vertices on the rounded edge over the straight side x < 0
    (edge line x = -(inr0 + T) ... checked as distance r_e to the fillet's centre line)."""
    _, (p, t) = tetra
    n = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    assert (n[:, 2] > 1e-9).all()
    e = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    _, c = np.unique(e, axis=0, return_counts=True)
    assert c.max() == 1
    _, cu = np.unique(np.sort(e, axis=1), axis=0, return_counts=True)
    assert cu.max() == 2 and (cu == 1).sum() > 0
    assert abs(p[:, 2].max()) < 1e-12
    # opening's straight side facing -x: sharp edge at x = -inr0; the fillet centre sits at x = -inr0 + T... mirrored:
    inr = 265.0 / (2 * np.sqrt(3.0))
    slope = np.arctan(120.0 / inr)
    inr0 = (60.0 - R_T) / 120.0 * inr + (R_T + 2.6) / np.sin(slope) + 5.0
    T = 10.0 * np.tan(np.radians(40.0))
    xc, zc = -inr0 - T, -10.0                              # fillet centre in the (x, z) plane (die material side)
    sel = (np.abs(p[:, 1]) < 20.0) & (p[:, 0] < -inr0 + 1e-9) & (p[:, 0] > xc + 1e-6) & (p[:, 2] > -8.0)
    sel &= p[:, 0] > -inr0 - T + 1e-6
    dist = np.hypot(p[sel, 0] - xc, p[sel, 2] - zc)
    assert sel.sum() >= 1 and np.allclose(dist, 10.0, atol=1e-9)


def test_committed_tool_files():
    """Requirement: every surface of decks/forming/tools is a binary STL under 1 MB that meshio reads back with the
    triangle count the generator gives at make_tools' settings (exact integer), placed with its lowest point as
    make_tools states (generator's closed position + travel, 1e-4 mm: float32 STL)."""
    import importlib.util
    from pathlib import Path

    import meshio

    root = Path(__file__).resolve().parents[1] / "decks" / "forming"
    spec = importlib.util.spec_from_file_location("make_tools", root / "make_tools.py")
    mk = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mk)
    for name, (gen, kw, lift) in mk.TOOLS.items():
        f = root / "tools" / name
        assert f.stat().st_size < 1_000_000
        m = meshio.read(f)
        p, t = gen(**kw)
        assert len(m.cells_dict["triangle"]) == len(t)
        assert abs(m.points[:, 2].min() - (p[:, 2].min() + lift)) < 1e-4
