"""Parametric rigid-tool surfaces (fdeck.physics.tools.generators): orientation, closure, dimensions, radii, files."""

import numpy as np
import pytest

from fdeck.physics.tools import generators as g

CASES = {
    "dd_punch": (g.double_dome, dict(part="punch")),
    "dd_punch_full": (g.double_dome, dict(part="punch", quarter=False, h=8.0)),
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


@pytest.mark.parametrize("name,quarter,h", [("dd_punch", True, 4.0), ("dd_punch_full", False, 8.0)])
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
    # and far tighter in practice: report the measured error relative to the volume
    assert abs(v - ref) / ref < 0.01


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
