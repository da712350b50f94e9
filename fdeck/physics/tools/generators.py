"""Parametric rigid-tool surfaces (numpy only) for the forming set-ups of MODELS.md sections 6.4-6.5.

Every generator returns ``(points (n, 3) float [mm], triangles (m, 3) int)``. Orientation convention: the normal
(p1 - p0) x (p2 - p0) of each triangle points OUT of the tool material, toward the blank's side (a die's upper face
points up, a punch's lower face points down). Punches are closed, watertight solids (forming face, side walls at the
model's outline, flat back); dies and blank holders are open sheets. Every forming face is a height field z(x, y)
on a tensor grid, its vertices placed exactly on the analytic surface; ``h`` is the target edge length [mm] in plan
on the curved parts, ``h_coarse`` the one on flat margins. ``quarter=True`` keeps x >= 0, y >= 0 (symmetry planes
x = 0 and y = 0); ``half=True`` keeps y >= 0.

Frame: die flange (upper face) at z = 0, blank on it (z in [0, t]), tools given in their CLOSED position (punch at
the end of its travel, clearance ``clearance`` to the die along the die's normal); a deck raises the punch by its
travel. Dimensions: see each generator; numbers not found in a publication are representative and say so.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


# ----------------------------------------------------------------------------------------------------------------
# meshing helpers
# ----------------------------------------------------------------------------------------------------------------
def _axis(half: float, fine: float, h: float, h_coarse: float, sym: bool) -> np.ndarray:
    """1-D node coordinates on [0, half] (or [-half, half] when not ``sym``): spacing <= h up to ``fine``,
    <= h_coarse beyond. (n,) [mm]."""
    fine = min(fine, half)
    a = np.linspace(0.0, fine, max(2, int(np.ceil(fine / h)) + 1))
    if half > fine:
        b = np.linspace(fine, half, max(2, int(np.ceil((half - fine) / h_coarse)) + 1))[1:]
        a = np.concatenate([a, b])
    return a if sym else np.concatenate([-a[:0:-1], a])


def _with(a: np.ndarray, *knots: float) -> np.ndarray:
    """Axis a with the given coordinates added (lobe centres, apexes: the bounding box then holds exactly)."""
    k = [v for v in knots if a[0] <= v <= a[-1]]
    a = np.unique(np.concatenate([a, k]))
    return a[np.concatenate([[True], np.diff(a) > 1e-6])]


def _sheet(xs, ys, z, up: bool):
    """Height-field sheet on the tensor grid xs (nx,), ys (ny,), heights z (nx, ny): points (nx*ny, 3), triangles
    with normals +z (``up``) or -z."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), z.ravel()])
    nx, ny = X.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    tri = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])  # counter-clockwise in plan
    return pts, (tri if up else tri[:, ::-1])


def _closed(xs, ys, z, z_back: float):
    """Closed solid between the height field z (nx, ny) and the flat back z = z_back: material on the back's side.
    Returns (points, triangles) oriented outward."""
    up = bool(z_back < z.min())                      # material below the face: face normals point up
    pts, tri = _sheet(xs, ys, z, up)
    nx, ny = z.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    loop = np.concatenate([idx[:, 0], idx[-1, 1:], idx[-2::-1, -1], idx[0, -2:0:-1]])  # counter-clockwise
    m = len(loop)
    back = pts[loop].copy()
    back[:, 2] = z_back
    centre = np.array([[0.5 * (xs[0] + xs[-1]), 0.5 * (ys[0] + ys[-1]), z_back]])
    n0 = len(pts)
    pts = np.vstack([pts, back, centre])
    bl = n0 + np.arange(m)
    nxt = np.roll(np.arange(m), -1)
    # side walls: quad (top_k, top_k+1, back_k+1, back_k); back lid: fan from its centre
    w1 = np.column_stack([loop, loop[nxt], bl[nxt]])
    w2 = np.column_stack([loop, bl[nxt], bl])
    lid = np.column_stack([np.full(m, n0 + m), bl[nxt], bl])
    # (top_k, top_k+1, back_k+1) winds outward when the back lies above the face, the fan (centre, back_k+1,
    # back_k) faces down: flip whichever does not face out for this solid
    walls = np.vstack([w1, w2])
    if up:
        walls = walls[:, ::-1]
    else:
        lid = lid[:, ::-1]
    tri = np.vstack([tri, walls, lid])
    return _drop_degenerate(pts, tri)


def _drop_degenerate(pts, tri):
    """Remove zero-area wall triangles (where the face touches the back) and unused points."""
    n = np.cross(pts[tri[:, 1]] - pts[tri[:, 0]], pts[tri[:, 2]] - pts[tri[:, 0]])
    tri = tri[np.linalg.norm(n, axis=1) > 1e-9]
    used, inv = np.unique(tri.ravel(), return_inverse=True)
    return pts[used], inv.reshape(-1, 3)


def signed_volume(points, triangles) -> float:
    """Enclosed volume [mm^3] by the divergence theorem, sum of p0.(p1 x p2)/6; positive when normals point out."""
    p = points[triangles]
    return float(np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0)


def write_surface(path, points, triangles) -> None:
    """Write a triangulated surface with meshio: binary STL for ``.stl``, Wavefront OBJ for ``.obj``."""
    import meshio

    path = Path(path)
    mesh = meshio.Mesh(np.asarray(points, float), [("triangle", np.asarray(triangles, int))])
    suffix = path.suffix.lower()
    if suffix == ".stl":
        meshio.write(path, mesh, file_format="stl", binary=True)
    elif suffix == ".obj":
        meshio.write(path, mesh, file_format="obj")
    else:
        raise ValueError(f"{path}: unknown surface suffix {suffix!r} (use .stl or .obj)")


# ----------------------------------------------------------------------------------------------------------------
# double dome
# ----------------------------------------------------------------------------------------------------------------
def _smin(a, b, k, level):
    """Polynomial smooth minimum of width k [mm] of two lobe heights: min(a, b) where |a - b| >= k, and where both
    lie on the flange (``level``), which the blend must not lower; the blend fades in over k below the flange."""
    hh = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    fade = np.clip((level - np.maximum(a, b)) / k, 0.0, 1.0)
    fade = fade * fade * (3.0 - 2.0 * fade)
    return np.minimum(a, b) - fade * k * hh * (1.0 - hh)


def double_dome_params(half_width=135.0, half_length=235.0, depth=60.0, entry_radius=10.0):
    """Lobe geometry of the double-dome die cavity: dict with the lobe centres' y [mm], the sphere radius R, its
    centre height zc, the entry torus (tube radius, plan radius of its centre circle) and the sphere/torus tangent
    plan radius. One lobe = spherical cavity of radius R joined to the flange by a torus of tube radius
    ``entry_radius``; the lobe's outer flange tangent circle has plan radius ``half_width`` and its bottom is
    ``depth`` below the flange, which fixes R by the tangency rho_c^2 + (R - depth + r)^2 = (R + r)^2."""
    rho_c, r = half_width, entry_radius
    R = (rho_c ** 2 + depth ** 2) / (2.0 * depth) - r
    return dict(yc=half_length - half_width, R=R, zc=R - depth, r=r, rho_c=rho_c, rho_t=rho_c * R / (R + r))


def _lobe(rho, p, off):
    """Height of one lobe's surface offset by ``off`` into the cavity (off = 0: die, off = c: punch face)."""
    R, r, zc, rho_c = p["R"] - off, p["r"] + off, p["zc"], p["rho_c"]
    rho_t = rho_c * R / (R + r)
    sph = zc - np.sqrt(np.maximum(R * R - rho ** 2, 0.0))
    tor = -p["r"] + np.sqrt(np.maximum(r * r - (rho - rho_c) ** 2, 0.0))
    return np.where(rho <= rho_t, sph, np.where(rho < rho_c, tor, off))


def double_dome_surface(x, y, off=0.0, half_width=135.0, half_length=235.0, depth=60.0, entry_radius=10.0,
                        blend=20.0):
    """z(x, y) [mm] of the double-dome die face (off = 0) or of its offset by ``off`` (the punch face): the smooth
    minimum (width ``blend``) of two lobes centred at (0, +-yc)."""
    p = double_dome_params(half_width, half_length, depth, entry_radius)
    z1 = _lobe(np.hypot(x, y - p["yc"]), p, off)
    z2 = _lobe(np.hypot(x, y + p["yc"]), p, off)
    return _smin(z1, z2, blend, off)


def double_dome(part="punch", quarter=True, h=4.0, h_coarse=20.0, half_width=135.0, half_length=235.0,
                depth=60.0, entry_radius=10.0, blend=20.0, clearance=2.6, extent=(320.0, 320.0),
                holder_gap=2.54, back=40.0):
    """Double-dome benchmark tools (woven-composite forming benchmark: Cao et al., Composites Part A 39 (2008);
    Khan, Mabrouki, Vidal-Salle, Boisse, J Mater Process Technol 210 (2010)): a female die with two spherical lobes
    joined by a saddle, the male punch, the flat blank holder around the die opening.

    part: "punch" (closed solid above its face), "die" (open sheet, normals up), "holder" (open sheet at z =
    ``holder_gap``, the blank thickness, normals down, with the die's opening cut out of it).
    Dimensions: die cavity 2*half_length x 2*half_width = 470 x 270 mm, ``depth`` 60 mm: the plan size and depth
    of the benchmark die as distributed in the benchmark's STL (270 x 470 x 60 mm, as reported by the public
    RTMsim-Py validation scripts, Pierce & Falzon, Engineering 3 (2017)); lobe shape (spheres, R = 171.9 mm with
    the defaults), entry radius 10 mm, saddle blend 20 mm, clearance 2.6 mm (3WEAVE 2.54 mm + 0.06) are
    REPRESENTATIVE choices (the benchmark's drawing was not found). The saddle between the lobes lies 27 mm above
    the lobe bottoms with the defaults. ``extent`` is the half size of the die/holder sheets (covers the 300 x 300
    quarter blank of [P] with margin); ``back`` the punch's thickness above its highest face point.
    """
    p = double_dome_params(half_width, half_length, depth, entry_radius)
    if part == "punch":
        xs = _axis(half_width, half_width, h, h_coarse, quarter)
        ys = _with(_axis(half_length, half_length, h, h_coarse, quarter), p["yc"], -p["yc"])
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        z = double_dome_surface(X, Y, clearance, half_width, half_length, depth, entry_radius, blend)
        return _closed(xs, ys, z, float(z.max()) + back)
    xs = _axis(extent[0], half_width + 2 * h, h, h_coarse, quarter)
    ys = _with(_axis(extent[1], half_length + 2 * h, h, h_coarse, quarter), p["yc"], -p["yc"])
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    if part == "die":
        return _sheet(xs, ys, double_dome_surface(X, Y, 0.0, half_width, half_length, depth, entry_radius, blend),
                      up=True)
    if part == "holder":
        pts, tri = _sheet(xs, ys, np.full(X.shape, holder_gap), up=False)
        # keep the cells whose four corners lie outside both lobes' outer tangent circles (a staircase opening)
        out = (np.hypot(X, Y - p["yc"]) >= half_width) & (np.hypot(X, Y + p["yc"]) >= half_width)
        keep = out.ravel()[tri].all(axis=1)
        return _drop_degenerate(pts, tri[keep])
    raise ValueError(f"double_dome: unknown part {part!r} (punch, die, holder)")


# ----------------------------------------------------------------------------------------------------------------
# square tube [J]
# ----------------------------------------------------------------------------------------------------------------
def _rounded_square_sd(x, y, a, rc):
    """Plan signed distance [mm] to a square of half side a with corner radius rc (negative inside)."""
    qx, qy = np.abs(x) - (a - rc), np.abs(y) - (a - rc)
    return np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0)) + np.minimum(np.maximum(qx, qy), 0.0) - rc


def step_profile(s, height, wall_angle, r_top, r_bot, off=0.0):
    """Height [mm] of a male step (plateau z = 0 for s << 0, base z = -height for s >> 0) along the plan signed
    distance s to its sharp top edge, the wall at ``wall_angle`` [deg] from horizontal, the top edge rounded with
    radius r_top (convex) and the foot with r_bot (concave); ``off`` offsets the curve by off along its upper normal
    (radii r_top + off and r_bot - off, same centres): the matching female tool's face."""
    al = np.radians(wall_angle)
    ta, sa, ca = np.tan(al), np.sin(al), np.cos(al)
    T, Tb = r_top * np.tan(al / 2), r_bot * np.tan(al / 2)
    sb = height / ta                                                 # sharp foot at s = +sb
    # mirrored die profile: u = -s runs from the plateau (u > 0) down the wall (u < 0)
    u = -np.asarray(s, float)
    Rt, Rb = r_top + off, r_bot - off
    cs, cz = -sb - Tb, -height + r_bot                               # concave fillet centre (u, z)
    z = np.full(u.shape, off)
    wall = (u + off * sa) * ta + off * ca
    z = np.where(u < T, -r_top + np.sqrt(np.maximum(Rt * Rt - (u - T) ** 2, 0.0)), z)
    z = np.where(u < T - Rt * sa, wall, z)
    z = np.where(u < cs + Rb * sa, cz - np.sqrt(np.maximum(Rb * Rb - (u - cs) ** 2, 0.0)), z)
    z = np.where(u < cs, -height + off, z)
    return z


def square_tube(part="lower", quarter=True, h=3.0, h_coarse=20.0, half_side=50.0, corner_radius=10.0,
                height=25.0, wall_angle=80.0, r_top=5.0, r_bot=5.0, clearance=0.3, extent=(160.0, 160.0),
                back=20.0):
    """Square-tube forming tools [J] (Nishi, Hirashima, Wang, JSOL, LS-DYNA conference): the 280 x 280 mm fabric
    is pushed by the upper tool over a square block (the lower tool), 20 mm of upper-tool travel.
    The tool geometry is not published: ALL dimensions are representative. Lower tool: closed solid, a square block
    2*half_side = 100 mm, plan corner radius 10 mm, ``height`` 25 mm above its base plane (more than the 20 mm
    travel), walls at 80 deg, top edge and foot radii 5 mm; its top face is z = 0. Upper tool: open sheet, the
    female offset of the lower tool by ``clearance`` (0.3 mm: fabric 0.23 mm), normals down, in the closed
    position; ``extent`` half size of the sheets (covers the 140 mm half blank)."""
    fine = half_side + height / np.tan(np.radians(wall_angle)) + r_bot + 2 * h
    xs = _axis(extent[0], fine, h, h_coarse, quarter)
    ys = _axis(extent[1], fine, h, h_coarse, quarter)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    s = _rounded_square_sd(X, Y, half_side, corner_radius)
    if part == "lower":
        return _closed(xs, ys, step_profile(s, height, wall_angle, r_top, r_bot), -height - back)
    if part == "upper":
        return _sheet(xs, ys, step_profile(s, height, wall_angle, r_top, r_bot, clearance), up=False)
    raise ValueError(f"square_tube: unknown part {part!r} (lower, upper)")


# ----------------------------------------------------------------------------------------------------------------
# tetrahedral punch (Boisse group)
# ----------------------------------------------------------------------------------------------------------------
def _span(lo: float, hi: float, fine_lo: float, fine_hi: float, h: float, h_coarse: float) -> np.ndarray:
    """1-D nodes on [lo, hi]: spacing <= h on [fine_lo, fine_hi], <= h_coarse outside; 0 is a node when inside."""
    parts = []
    for a, b, s in ((lo, fine_lo, h_coarse), (fine_lo, fine_hi, h), (fine_hi, hi, h_coarse)):
        if b > a:
            parts.append(np.linspace(a, b, max(2, int(np.ceil((b - a) / s)) + 1)))
    return _with(np.concatenate(parts), 0.0)


def _closest_on_triangle(p, a, b, c):
    """Closest points (n, 3) on the triangle (a, b, c) to the points p (n, 3) (Voronoi regions of the vertices,
    edges and face; Ericson, Real-Time Collision Detection, 2005, section 5.1.5)."""
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2, d3, d4, d5, d6 = ap @ ab, ap @ ac, bp @ ab, bp @ ac, cp @ ab, cp @ ac
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        on_ab = a + np.nan_to_num(d1 / (d1 - d3))[:, None] * ab
        on_ac = a + np.nan_to_num(d2 / (d2 - d6))[:, None] * ac
        on_bc = b + np.nan_to_num((d4 - d3) / ((d4 - d3) + (d5 - d6)))[:, None] * (c - b)
        den = va + vb + vc
        face = a + np.nan_to_num(vb / den)[:, None] * ab + np.nan_to_num(vc / den)[:, None] * ac
    cond = [(d1 <= 0) & (d2 <= 0), (d3 >= 0) & (d4 <= d3), (vc <= 0) & (d1 >= 0) & (d3 <= 0),
            (d6 >= 0) & (d5 <= d6), (vb <= 0) & (d2 >= 0) & (d6 <= 0),
            (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)]
    out = face.copy()
    for m, q in reversed(list(zip(cond, [np.broadcast_to(a, p.shape), np.broadcast_to(b, p.shape), on_ab,
                                         np.broadcast_to(c, p.shape), on_ac, on_bc]))):
        out = np.where(m[:, None], q, out)
    return out


def tetra_core(apex_z=-50.0, side=265.0, core_height=120.0):
    """Vertices (4, 3) [mm] of the core tetrahedron, apex down at (0, 0, apex_z), top equilateral triangle of
    ``side`` at apex_z + core_height with one vertex on +x (symmetry plane y = 0), and its faces (4, 3) wound
    outward."""
    Rc = side / np.sqrt(3.0)
    ang = np.radians([0.0, 120.0, 240.0])
    top = np.column_stack([Rc * np.cos(ang), Rc * np.sin(ang), np.full(3, apex_z + core_height)])
    v = np.vstack([[0.0, 0.0, apex_z], top])
    faces = np.array([[0, 2, 1], [0, 3, 2], [0, 1, 3], [1, 2, 3]])
    return v, faces


def _dist_to_tetra(p, v, faces):
    """Euclidean distance (n,) [mm] of the points p (n, 3) to the solid tetrahedron (0 inside)."""
    n = np.cross(v[faces[:, 1]] - v[faces[:, 0]], v[faces[:, 2]] - v[faces[:, 0]])
    inside = np.all(np.einsum("nfk,fk->nf", p[:, None, :] - v[faces[:, 0]][None], n) <= 0.0, axis=1)
    d = np.min([np.linalg.norm(p - _closest_on_triangle(p, *v[f]), axis=1) for f in faces], axis=0)
    return np.where(inside, 0.0, d)


def tetra_lower_envelope(x, y, radius=10.0, **core):
    """Lowest z [mm] of the rounded tetrahedron (core tetrahedron + ball of ``radius``) above each plan point
    (x, y) (arrays of one shape), +inf outside its footprint. The distance to the convex core is convex along a
    vertical line, so a ternary search finds its minimum and a bisection its lower crossing of ``radius``."""
    v, faces = tetra_core(**core)
    shape = np.shape(x)
    xy = np.column_stack([np.ravel(x), np.ravel(y)])

    def f(z):
        return _dist_to_tetra(np.column_stack([xy, z]), v, faces) - radius

    lo = np.full(len(xy), v[:, 2].min() - radius - 1.0)
    hi = np.full(len(xy), v[:, 2].max())
    for _ in range(80):                                           # ternary search: z of the minimum distance
        m1, m2 = lo + (hi - lo) / 3, hi - (hi - lo) / 3
        left = f(m1) <= f(m2)
        hi, lo = np.where(left, m2, hi), np.where(left, lo, m1)
    zmin = 0.5 * (lo + hi)
    inside = f(zmin) <= 0.0
    a, b = np.full(len(xy), v[:, 2].min() - radius - 1.0), zmin   # f(a) > 0 >= f(b) where inside
    for _ in range(60):
        m = 0.5 * (a + b)
        pos = f(m) > 0.0
        a, b = np.where(pos, m, a), np.where(pos, b, m)
    return np.where(inside, b, np.inf).reshape(shape)


def _triangle_sd(x, y, inradius):
    """Plan signed distance [mm] to the equilateral triangle of the given inradius centred at 0, one vertex on +x."""
    nrm = np.radians([180.0, 60.0, -60.0])                         # outward edge normals
    pts = np.stack([x, y], axis=-1)
    dplane = np.max([pts @ np.array([np.cos(a), np.sin(a)]) - inradius for a in nrm], axis=0)
    R = 2.0 * inradius
    ang = np.radians([0.0, 120.0, 240.0])
    V = np.column_stack([R * np.cos(ang), R * np.sin(ang)])
    dseg = []
    for i in range(3):
        a_, b_ = V[i], V[(i + 1) % 3]
        t = np.clip(((pts - a_) @ (b_ - a_)) / ((b_ - a_) @ (b_ - a_)), 0.0, 1.0)
        dseg.append(np.linalg.norm(pts - (a_ + t[..., None] * (b_ - a_)), axis=-1))
    return np.where(dplane <= 0.0, dplane, np.min(dseg, axis=0))


def tetrahedron(part="punch", half=True, h=4.0, h_coarse=25.0, side=265.0, core_height=120.0, radius=10.0,
                lowest=-60.0, clearance=2.6, die_gap=5.0, entry_radius=10.0, wall_angle=80.0, wall_cut=20.0,
                extent=(300.0, 250.0), back=30.0):
    """Tetrahedral punch test (Allaoui, Boisse, Chatel, Hamila, Hivet, Soulat, Vidal-Salle, Composites Part A 42
    (2011) 612-622; used with 3WEAVE in Pazmino et al., Composites Part A 72 (2015)): a tetrahedral punch pushes
    the fabric through a triangular opening of an open die. Published tool dimensions were not found: ALL numbers
    are REPRESENTATIVE.

    part "punch": closed solid, the core tetrahedron (apex down, top equilateral triangle of ``side`` 265 mm,
    ``core_height`` 120 mm; lateral faces at 57.5 deg) rounded by ``radius`` 10 mm on every edge and at the apex
    (Minkowski sum with a ball), mounted under a flat plate at the core's top face, lowest point at ``lowest``
    (closed position = end of travel; the die plane is z = 0). part "die": open sheet, normals up, flange z = 0
    with a triangular opening: the punch's section at z = 0 plus ``clearance`` and ``die_gap`` (plan), entry edge
    radius ``entry_radius``, wall at ``wall_angle`` cut ``wall_cut`` below the flange (the cut rim follows the grid,
    below anything the blank reaches). ``half``: y >= 0 (symmetry plane through the apex and one top vertex).
    """
    apex_z = lowest + radius
    core = dict(apex_z=apex_z, side=side, core_height=core_height)
    Rc = side / np.sqrt(3.0)
    ylo = 0.0 if half else -side / 2 - radius - h
    if part == "punch":
        xs = _span(-Rc / 2 - radius - h, Rc + radius + h, -Rc / 2 - radius - h, Rc + radius + h, h, h)
        ys = _span(ylo, side / 2 + radius + h, ylo, side / 2 + radius + h, h, h)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        z = np.minimum(tetra_lower_envelope(X, Y, radius, **core), apex_z + core_height)
        return _closed(xs, ys, z, apex_z + core_height + back)
    if part == "die":
        inr = side / (2 * np.sqrt(3.0))
        slope = np.arctan(core_height / inr)
        inr0 = (0.0 - apex_z) / core_height * inr + (radius + clearance) / np.sin(slope) + die_gap
        fine = 2 * inr0 + entry_radius + 3 * h
        xs = _span(-extent[0], extent[0], -inr0 - entry_radius - 3 * h, fine, h, h_coarse)
        ys = _span(0.0 if half else -extent[1], extent[1], 0.0 if half else -fine, fine, h, h_coarse)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        z = step_profile(-_triangle_sd(X, Y, inr0), 2 * wall_cut, wall_angle, entry_radius, entry_radius)
        pts, tri = _sheet(xs, ys, z, up=True)
        keep = (pts[tri, 2] >= -wall_cut).any(axis=1)
        return _drop_degenerate(pts, tri[keep])
    raise ValueError(f"tetrahedron: unknown part {part!r} (punch, die)")


def flange_holder(points, triangles, level=0.0, tol=1e-9):
    """Blank holder matching a die's flat flange: the die triangles (``points`` (n, 3), ``triangles`` (m, 3), normals
    up) whose three corners lie on the flange plane z = ``level`` (within ``tol`` mm), turned over (normals down),
    as an open sheet at the same height; a deck lifts it by the blank thickness plus clearance (``offset``). Its
    opening is the die's opening up to where the entry radius starts (the staircase of the die's grid there), so the
    holder presses the flange and never the radius. Returns (points, triangles)."""
    flat = (np.abs(points[triangles, 2] - level) <= tol).all(axis=1)
    return _drop_degenerate(points, triangles[flat][:, ::-1])
