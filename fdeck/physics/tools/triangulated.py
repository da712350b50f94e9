"""Triangulated rigid surfaces: signed distance of a point by closest point on the triangles near it.

Narrow phase: the closest point of a triangle and the feature it lies on (face, edge or vertex) follow the region
tests of Ericson (Real-Time Collision Detection, 2005, section 5.1.5). The sign of the distance comes from the
angle-weighted pseudonormal of that feature (Baerentzen and Aanaes, "Signed distance computation using the angle
weighted pseudonormal", IEEE TVCG 11(3), 2005): face normal on a face, the mean of the two face normals on an edge,
the angle-weighted mean of the incident face normals at a vertex. For a consistently oriented surface this gives the
right side everywhere near it, convex and concave edges alike. Triangle normals (p1 - p0) x (p2 - p0) point out of
the tool, toward the side where the blank may be; a surface may be an open sheet (a die face).

Broad phase: a uniform grid in the tool's own frame (a rigid tool only translates, so the grid is built once). Each
triangle is listed in every cell that its bounding box, grown by the search radius r, overlaps; a point then finds
every triangle within r of it in its own cell: one cell look-up and a handful of triangles per query, so a cycle
costs O(blank nodes), whatever the number of facets. A point with no triangle within r is "far" (distance reported
as r): the contact's step bound keeps a node from travelling that far in one cycle. A point behind the rim of an
open sheet (closest to a boundary edge or vertex, on the back side) is far too: it went round the edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fdeck.jit import njit

FACE, VERTEX, EDGE = 0, 1, 4  # region codes: FACE; VERTEX + k (k = 0, 1, 2); EDGE + k (edges 01, 12, 20)
MAX_CELLS = 4_000_000


@dataclass
class Surface:
    """A triangulated surface ready for queries (all arrays C-contiguous, tool frame, mm).

    P (nv, 3) vertices; T (nt, 3) int64 triangles; face_n (nt, 3) unit normals; edge_n (nt, 3, 3) pseudonormal of
    edge k (01, 12, 20) of each triangle; vert_n (nv, 3) vertex pseudonormals; rim_e (nt, 3), rim_v (nv,) bool: the
    edge or vertex lies on the rim of an open sheet (an edge of one triangle); grid: lo (3,) corner, h cell size,
    dims (3,) int64, start (n_cell + 1,) int64 and items (n_item,) int64 (CSR cell -> triangles); r search radius.
    """

    P: np.ndarray
    T: np.ndarray
    face_n: np.ndarray
    edge_n: np.ndarray
    vert_n: np.ndarray
    rim_e: np.ndarray
    rim_v: np.ndarray
    lo: np.ndarray
    h: float
    dims: np.ndarray
    start: np.ndarray
    items: np.ndarray
    r: float

    def arrays(self) -> tuple:
        return (self.P, self.T, self.face_n, self.edge_n, self.vert_n, self.rim_e, self.rim_v, self.lo, self.h,
                self.dims, self.start, self.items, self.r)


def _read_mesh(path: Path):
    """meshio's mesh of a surface file. meshio's Abaqus reader knows R3D3 but not R3D4, Abaqus's 4-node rigid
    facet; an .inp's R3D4 elements are read as S4R, the 4-node shell whose connectivity meshio maps to a quad
    (only the nodes and their order are used here: the facet's normal follows that order in both)."""
    import io
    import re

    import meshio

    if path.suffix.lower() != ".inp":
        return meshio.read(path)
    text, rewritten = re.subn(r"(type\s*=\s*)R3D4\b", r"\1S4R", path.read_text(errors="replace"), flags=re.I)
    if not rewritten:  # meshio reads it as it is (its public reader)
        return meshio.read(path)
    from meshio.abaqus._abaqus import read_buffer

    buffer = io.StringIO(text)
    buffer.name = str(path)  # meshio finds *INCLUDE files beside it (R3D4 elements inside those are not rewritten)
    return read_buffer(buffer)


def read(path: Path, part: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(points (n, 3), triangles (m, 3) int64) of a surface file that meshio reads (STL, OBJ, Abaqus .inp, ...);
    quadrilaterals (R3D4, S4, any quad) are split into two triangles; ``part`` names a cell set (an Abaqus element
    set) to keep.
    Raises ValueError with a plain message on a file that holds no triangles or quadrilaterals."""
    mesh = _read_mesh(Path(path))
    tris = []
    for k, block in enumerate(mesh.cells):
        data = np.asarray(block.data, np.int64)
        if part is not None:
            if part not in mesh.cell_sets:
                raise ValueError(f"no cell set '{part}' in {path.name} (sets: {', '.join(sorted(mesh.cell_sets))})")
            keep = mesh.cell_sets[part][k]
            data = data[np.asarray(keep, np.int64)] if keep is not None and len(keep) else data[:0]
        if block.type == "triangle":
            tris.append(data)
        elif block.type == "quad":
            tris += [data[:, [0, 1, 2]], data[:, [0, 2, 3]]]
    if not tris or sum(len(t) for t in tris) == 0:
        raise ValueError(f"{path.name} holds no triangles or quadrilaterals")
    T = np.concatenate(tris)
    used = np.unique(T)
    remap = np.full(len(mesh.points), -1, np.int64)
    remap[used] = np.arange(len(used))
    P = np.asarray(mesh.points, float)[used]
    if P.shape[1] == 2:
        P = np.column_stack([P, np.zeros(len(P))])
    return np.ascontiguousarray(P), np.ascontiguousarray(remap[T])


def pseudonormals(P: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, ...]:
    """(face normals (nt, 3), edge pseudonormals (nt, 3, 3), vertex pseudonormals (nv, 3), rim edges (nt, 3) bool,
    rim vertices (nv,) bool); raises ValueError on a degenerate triangle or on an edge shared by more than two
    triangles."""
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    cr = np.cross(b - a, c - a)
    area2 = np.linalg.norm(cr, axis=1)
    if np.any(area2 <= 1e-12 * max(1.0, float(np.ptp(P, axis=0).max()) ** 2)):
        bad = np.nonzero(area2 <= 1e-12 * max(1.0, float(np.ptp(P, axis=0).max()) ** 2))[0]
        raise ValueError(f"{len(bad)} degenerate triangles (zero area), e.g. triangles {(bad[:5] + 1).tolist()}")
    fn = cr / area2[:, None]
    # vertex pseudonormal: incident face normals weighted by the triangle's angle at the vertex
    vn = np.zeros_like(P)
    for k in range(3):
        e1 = P[T[:, (k + 1) % 3]] - P[T[:, k]]
        e2 = P[T[:, (k + 2) % 3]] - P[T[:, k]]
        cosang = np.einsum("ij,ij->i", e1, e2) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
        np.add.at(vn, T[:, k], np.arccos(np.clip(cosang, -1.0, 1.0))[:, None] * fn)
    vn /= np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]
    # edge pseudonormal: the two faces' normals added (one face on a boundary edge)
    edges = np.stack([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]], axis=1).reshape(-1, 2)  # (3 nt, 2)
    key = np.sort(edges, axis=1)
    uniq, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if np.any(counts > 2):
        bad = uniq[counts > 2][:3] + 1
        raise ValueError(f"{int(np.sum(counts > 2))} edges are shared by more than two triangles (non-manifold), "
                         f"e.g. between vertices {bad.tolist()}")
    acc = np.zeros((len(uniq), 3))
    np.add.at(acc, inv.ravel(), np.repeat(fn, 3, axis=0))
    en = acc[inv.ravel()]
    en /= np.maximum(np.linalg.norm(en, axis=1), 1e-300)[:, None]
    rim_e = (counts[inv.ravel()] == 1).reshape(-1, 3)
    rim_v = np.zeros(len(P), bool)
    rim_v[edges[rim_e.ravel()].ravel()] = True
    return fn, np.ascontiguousarray(en.reshape(-1, 3, 3)), vn, np.ascontiguousarray(rim_e), rim_v


def build(P: np.ndarray, T: np.ndarray, r: float) -> Surface:
    """Query-ready surface with search radius r [mm]: pseudonormals and the grid (cell size at least r and the
    median edge length, grown until the grid has at most MAX_CELLS cells)."""
    P, T = np.ascontiguousarray(P, float), np.ascontiguousarray(T, np.int64)
    fn, en, vn, rim_e, rim_v = pseudonormals(P, T)
    edge = np.linalg.norm(P[T[:, 1]] - P[T[:, 0]], axis=1)
    lo, hi = P.min(axis=0) - 1.01 * r, P.max(axis=0) + 1.01 * r
    h = max(r, float(np.median(edge)))
    while True:
        dims = np.maximum(1, np.ceil((hi - lo) / h)).astype(np.int64)
        if int(np.prod(dims)) <= MAX_CELLS:
            break
        h *= 1.5
    tlo = np.minimum(np.minimum(P[T[:, 0]], P[T[:, 1]]), P[T[:, 2]]) - r
    thi = np.maximum(np.maximum(P[T[:, 0]], P[T[:, 1]]), P[T[:, 2]]) + r
    i0 = np.clip(np.floor((tlo - lo) / h).astype(np.int64), 0, dims - 1)
    i1 = np.clip(np.floor((thi - lo) / h).astype(np.int64), 0, dims - 1)
    start, items = _fill_grid(i0, i1, dims)
    return Surface(P, T, fn, en, vn, rim_e, rim_v, lo, h, dims, start, items, float(r))


@njit
def _fill_grid(i0, i1, dims):
    """CSR cell -> triangles from each triangle's cell range [i0, i1] (inclusive, (nt, 3) each); triangles in
    increasing order within a cell (so ties resolve the same way on any machine)."""
    count = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
    _scan(i0, i1, dims, count, count, False)  # count[c + 1] = triangles of cell c
    start = np.cumsum(count)
    items = np.empty(start[-1], np.int64)
    _scan(i0, i1, dims, start[:-1].copy(), items, True)
    return start, items


@njit
def _scan(i0, i1, dims, cursor, items, write):
    """Visit every (triangle, cell) pair: count into cursor[c + 1], or write t at items[cursor[c]] and advance."""
    for t in range(i0.shape[0]):
        for i in range(i0[t, 0], i1[t, 0] + 1):
            for j in range(i0[t, 1], i1[t, 1] + 1):
                for k in range(i0[t, 2], i1[t, 2] + 1):
                    c = (i * dims[1] + j) * dims[2] + k
                    if write:
                        items[cursor[c]] = t
                        cursor[c] += 1
                    else:
                        cursor[c + 1] += 1


@njit
def closest_on_triangle(ax, ay, az, bx, by, bz, cx, cy, cz, px, py, pz):
    """(qx, qy, qz, region) closest point of triangle abc to p and the feature it lies on (FACE, VERTEX + k,
    EDGE + k), by Voronoi-region tests in barycentric terms (Ericson 2005, 5.1.5)."""
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    apx, apy, apz = px - ax, py - ay, pz - az
    d1 = abx * apx + aby * apy + abz * apz
    d2 = acx * apx + acy * apy + acz * apz
    if d1 <= 0.0 and d2 <= 0.0:
        return ax, ay, az, VERTEX
    bpx, bpy, bpz = px - bx, py - by, pz - bz
    d3 = abx * bpx + aby * bpy + abz * bpz
    d4 = acx * bpx + acy * bpy + acz * bpz
    if d3 >= 0.0 and d4 <= d3:
        return bx, by, bz, VERTEX + 1
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / (d1 - d3)
        return ax + s * abx, ay + s * aby, az + s * abz, EDGE
    cpx, cpy, cpz = px - cx, py - cy, pz - cz
    d5 = abx * cpx + aby * cpy + abz * cpz
    d6 = acx * cpx + acy * cpy + acz * cpz
    if d6 >= 0.0 and d5 <= d6:
        return cx, cy, cz, VERTEX + 2
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / (d2 - d6)
        return ax + s * acx, ay + s * acy, az + s * acz, EDGE + 2
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz), EDGE + 1
    den = 1.0 / (va + vb + vc)
    v, w = vb * den, vc * den
    return ax + v * abx + w * acx, ay + v * aby + w * acy, az + v * abz + w * acz, FACE


@njit
def distance(P, T, face_n, edge_n, vert_n, rim_e, rim_v, lo, h, dims, start, items, r, x0, x1, x2):
    """(d [mm], n0, n1, n2) signed distance and outward unit normal of the point (x0, x1, x2) in the tool's frame;
    (r, 0, 0, 0) when no triangle lies within the search radius r, or when the point lies behind an open sheet's rim
    and beyond it (closest to a rim edge or vertex, on the back side, off the rim's normal line): such a point has
    gone round the sheet's edge, not through its face, and pushing it back through the face would create energy."""
    d, n0, n1, n2, _ = closest(P, T, face_n, edge_n, vert_n, rim_e, rim_v, lo, h, dims, start, items, r, x0, x1, x2)
    return d, n0, n1, n2


@njit
def closest(P, T, face_n, edge_n, vert_n, rim_e, rim_v, lo, h, dims, start, items, r, x0, x1, x2):
    """``distance`` and, fifth, the unsigned distance to the nearest triangle [mm] (r when none lies within r, and
    the true one for a point that went round a rim): how far the point must move before it can touch the tool."""
    i = int(math.floor((x0 - lo[0]) / h))
    j = int(math.floor((x1 - lo[1]) / h))
    k = int(math.floor((x2 - lo[2]) / h))
    if i < 0 or j < 0 or k < 0 or i >= dims[0] or j >= dims[1] or k >= dims[2]:
        return r, 0.0, 0.0, 0.0, r
    c = (i * dims[1] + j) * dims[2] + k
    best, tbest, rbest = r * r, -1, 0
    q0 = q1 = q2 = 0.0
    for s in range(start[c], start[c + 1]):
        t = items[s]
        a, b, cc = T[t, 0], T[t, 1], T[t, 2]
        y0, y1, y2, region = closest_on_triangle(P[a, 0], P[a, 1], P[a, 2], P[b, 0], P[b, 1], P[b, 2],
                                                 P[cc, 0], P[cc, 1], P[cc, 2], x0, x1, x2)
        dd = (x0 - y0) ** 2 + (x1 - y1) ** 2 + (x2 - y2) ** 2
        if dd < best:
            best, tbest, rbest = dd, t, region
            q0, q1, q2 = y0, y1, y2
    if tbest < 0:
        return r, 0.0, 0.0, 0.0, r
    if rbest == FACE:
        p0, p1, p2 = face_n[tbest, 0], face_n[tbest, 1], face_n[tbest, 2]
        rim = False
    elif rbest >= EDGE:
        e = rbest - EDGE
        p0, p1, p2 = edge_n[tbest, e, 0], edge_n[tbest, e, 1], edge_n[tbest, e, 2]
        rim = rim_e[tbest, e]
    else:
        v = T[tbest, rbest - VERTEX]
        p0, p1, p2 = vert_n[v, 0], vert_n[v, 1], vert_n[v, 2]
        rim = rim_v[v]
    dist = math.sqrt(best)
    r0, r1, r2 = x0 - q0, x1 - q1, x2 - q2
    if dist <= 1e-12 * h:  # on the surface: the pseudonormal is the normal
        return 0.0, p0, p1, p2, 0.0
    sign = 1.0 if r0 * p0 + r1 * p1 + r2 * p2 >= 0.0 else -1.0
    if rim and sign < 0.0:
        # behind a rim: "far" only if the point is also beyond the rim within the sheet's plane (it went round the
        # edge); straight behind it (a node on a symmetry plane under a quarter tool's rim) it has penetrated
        rn = r0 * p0 + r1 * p1 + r2 * p2
        if (r0 - rn * p0) ** 2 + (r1 - rn * p1) ** 2 + (r2 - rn * p2) ** 2 > 1e-12 * dist * dist:
            return r, 0.0, 0.0, 0.0, dist
    return sign * dist, sign * r0 / dist, sign * r1 / dist, sign * r2 / dist, dist
