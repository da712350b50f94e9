"""Meshes as arrays: the built-in block generator and meshio import, with named node and element sets."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fdeck.compile.errors import CompileError

# meshio cell types fdeck reads, with their node counts: 8-node hexahedra (solids), 4-node quadrilaterals and
# 3-node triangles (shells and membranes).
SUPPORTED_TYPES = {"hexahedron": 8, "quad": 4, "triangle": 3}


@dataclass
class MeshArrays:
    """X (n_node, 3) [mm]; cells: cell type -> connectivity (n_el, k), 0-based; node_sets: name -> node indices;
    element_sets: name -> (cell type, element indices in that block); ids: cell type -> user ids (n_el,);
    cell_data: name -> cell type -> per-element values (n_el,) or (n_el, k) read from a mesh file."""

    X: np.ndarray
    cells: dict[str, np.ndarray]
    node_sets: dict[str, np.ndarray] = field(default_factory=dict)
    element_sets: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    ids: dict[str, np.ndarray] = field(default_factory=dict)
    cell_data: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)


def block(origin, size, divisions=None, element_size=None) -> MeshArrays:
    """Structured hexahedra on [origin, origin + size]; face node sets xmin..zmax, sets `all`."""
    if divisions is None:
        divisions = [max(1, math.ceil(s / element_size - 1e-9)) for s in size]
    nx, ny, nz = divisions
    axes = [np.linspace(o, o + s, n + 1) for o, s, n in zip(origin, size, divisions)]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    X = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1)
    nid = np.arange(len(X)).reshape(nx + 1, ny + 1, nz + 1)
    i, j, k = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    conn = np.stack([nid[i, j, k], nid[i + 1, j, k], nid[i + 1, j + 1, k], nid[i, j + 1, k],
                     nid[i, j, k + 1], nid[i + 1, j, k + 1], nid[i + 1, j + 1, k + 1], nid[i, j + 1, k + 1]], 1)
    sets = {"all": np.arange(len(X))}
    for a, name in enumerate("xyz"):
        sets[f"{name}min"] = nid.take(0, axis=a).ravel()
        sets[f"{name}max"] = nid.take(-1, axis=a).ravel()
    m = MeshArrays(X, {"hexahedron": conn}, {k: np.sort(v) for k, v in sets.items()})
    m.ids = {"hexahedron": np.arange(1, len(conn) + 1)}
    m.element_sets["all"] = {"hexahedron": np.arange(len(conn))}
    return m


def diagonal_block(origin, size, divisions=None, element_size=None) -> MeshArrays:
    """Hexahedra whose edges in x-y run at +-45 deg (a diamond lattice extruded along z), for fabrics with fibres at
    +-45 deg: an element can then shear along its fibres without stretching them (no intra-ply shear locking).

    divisions (nx, ny, nz): nx, ny count half-diagonals d = size / n along x and y (even, so that the block's
    corners are lattice nodes), nz layers; element_size h: the diamonds' edge, d = h / sqrt(2), nx, ny rounded up to
    even (so 4.24 mm on 300 mm gives 102, the exact 3 sqrt(2) gives 100). The spacings size[0] / nx and size[1] / ny
    must be equal (else the edges are not at +-45 deg): refused otherwise. Lattice nodes (i, j) with i + j even;
    each diamond is centred at a point with i + j odd. A diamond cut by a side of the block is one element too: the
    half-diamond, a triangle, as a hexahedron with one edge collapsed (its corner beyond the side takes the next
    corner's node). A collapsed hexahedron interpolates linearly in the triangle (a prism), so its two edges along
    the fibres stay fibre-aligned (a mid-side node on the block's side instead would stretch the fibres at first
    order; tests/test_diagonal_lattice.py); its Jacobian is positive at every integration point and zero along the
    collapsed edge. A 300 x 300 mm quarter with d = 3 mm (4.24 mm edges) has 4 900 diamonds and 200 halves per
    layer, the 5 100 of the published +-45 meshes (MODELS.md 6.4). Node sets xmin..zmax (faces) and `all`; element
    set `all`."""
    if divisions is None:
        divisions = [2 * max(1, math.ceil(s / (2 * element_size / math.sqrt(2)) - 1e-9)) for s in size[:2]]
        divisions.append(max(1, math.ceil(size[2] / element_size - 1e-9)))
    nx, ny, nz = divisions
    if nx % 2 or ny % 2:
        raise CompileError([(("mesh", "block", "divisions"),
                             f"a diagonal lattice needs even divisions along x and y, got {nx} and {ny}")])
    dx, dy = size[0] / nx, size[1] / ny
    if abs(dx - dy) > 1e-9 * max(dx, dy):
        raise CompileError([(("mesh", "block"), f"a diagonal lattice needs equal spacings size / divisions along x "
                             f"and y (edges at +-45 deg), got {dx:.6g} and {dy:.6g} mm: choose divisions "
                             f"[{nx}, {2 * round(size[1] / dx / 2)}, {nz}] or a size to match")])
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), indexing="ij")
    used = (i + j) % 2 == 0  # lattice nodes
    plane = np.full((nx + 1, ny + 1), -1, np.int64)
    plane[used] = np.arange(used.sum())
    ci, cj = np.nonzero((i + j) % 2 == 1)
    # corners counter-clockwise seen from +z: east, north, west, south; a corner beyond a side (at most one: the
    # block's corners are nodes) takes the node of the corner after it
    steps = np.array([(1, 0), (0, 1), (-1, 0), (0, -1)])
    a, b = ci[:, None] + steps[:, 0], cj[:, None] + steps[:, 1]
    out = (a < 0) | (a > nx) | (b < 0) | (b > ny)
    a, b = np.where(out, np.roll(a, -1, axis=1), a), np.where(out, np.roll(b, -1, axis=1), b)
    quad = plane[a, b]
    layers = nz + 1
    xy = np.stack([i[used], j[used]], 1) * (np.asarray(size[:2], float) / (nx, ny)) + np.asarray(origin[:2], float)
    z = np.linspace(origin[2], origin[2] + size[2], layers)
    X = np.column_stack([np.repeat(xy, layers, axis=0), np.tile(z, len(xy))])
    k = np.arange(nz)
    bottom = (quad[:, None, :] * layers + k[None, :, None]).reshape(-1, 4)
    conn = np.concatenate([bottom, bottom + 1], axis=1)
    node_i, node_j, node_k = np.repeat(i[used], layers), np.repeat(j[used], layers), np.tile(np.arange(layers), len(xy))
    sets = {"all": np.arange(len(X)), "xmin": node_i == 0, "xmax": node_i == nx, "ymin": node_j == 0,
            "ymax": node_j == ny, "zmin": node_k == 0, "zmax": node_k == nz}
    sets = {name: (np.nonzero(s)[0] if s.dtype == bool else s) for name, s in sets.items()}
    m = MeshArrays(X, {"hexahedron": conn}, sets)
    m.ids = {"hexahedron": np.arange(1, len(conn) + 1)}
    m.element_sets["all"] = {"hexahedron": np.arange(len(conn))}
    return m


def plate(origin, size, divisions=None, element_size=None, triangles=False) -> MeshArrays:
    """Structured quadrilaterals (or each split into two triangles) on the rectangle [origin, origin + size] in the
    plane z = origin[2], node order counter-clockwise seen from +z (normal +z). Node sets xmin, xmax, ymin, ymax
    (edges) and `all`; element set `all`."""
    if divisions is None:
        divisions = [max(1, math.ceil(s / element_size - 1e-9)) for s in size]
    nx, ny = divisions
    xs = np.linspace(origin[0], origin[0] + size[0], nx + 1)
    ys = np.linspace(origin[1], origin[1] + size[1], ny + 1)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    X = np.stack([gx.ravel(), gy.ravel(), np.full(gx.size, float(origin[2]))], axis=1)
    nid = np.arange(len(X)).reshape(nx + 1, ny + 1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    i, j = i.ravel(), j.ravel()
    quads = np.stack([nid[i, j], nid[i + 1, j], nid[i + 1, j + 1], nid[i, j + 1]], 1)
    if triangles:
        ctype, conn = "triangle", np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    else:
        ctype, conn = "quad", quads
    sets = {"all": np.arange(len(X)), "xmin": nid[0], "xmax": nid[-1], "ymin": nid[:, 0], "ymax": nid[:, -1]}
    m = MeshArrays(X, {ctype: conn}, {k: np.sort(v) for k, v in sets.items()})
    m.ids = {ctype: np.arange(1, len(conn) + 1)}
    m.element_sets["all"] = {ctype: np.arange(len(conn))}
    return m


def read_file(path: Path) -> MeshArrays:
    """Any mesh meshio reads; keeps its point sets and cell sets (Abaqus *NSET/*ELSET, Gmsh physical groups)."""
    import meshio

    try:
        mesh = meshio.read(path)
    except Exception as exc:  # meshio raises many types; all mean "cannot read this file"
        raise CompileError([(("mesh", "file"), f"cannot read mesh file '{path}': {exc}")]) from None
    X = np.zeros((len(mesh.points), 3))
    X[:, : mesh.points.shape[1]] = mesh.points
    cells, block_of = {}, []
    for b, cb in enumerate(mesh.cells):
        if cb.type in SUPPORTED_TYPES:
            cells.setdefault(cb.type, []).append(cb.data)
            block_of.append((b, cb.type, sum(len(c) for c in cells[cb.type][:-1])))
    if not cells:
        kinds = sorted({cb.type for cb in mesh.cells})
        raise CompileError([(("mesh", "file"), f"no supported elements in '{path}' (found {kinds}; "
                                                 f"supported: {sorted(SUPPORTED_TYPES)})")])
    m = MeshArrays(X, {t: np.concatenate(c).astype(np.int64) for t, c in cells.items()})
    m.ids = {t: np.arange(1, len(c) + 1) for t, c in m.cells.items()}
    m.node_sets = {k: np.sort(np.asarray(v, np.int64).ravel()) for k, v in mesh.point_sets.items()}
    m.node_sets["all"] = np.arange(len(X))
    for name, per_block in mesh.cell_sets.items():
        es = {}
        for b, t, offset in block_of:
            idx = np.asarray(per_block[b], np.int64).ravel() if b < len(per_block) and per_block[b] is not None else []
            if len(idx):
                es[t] = np.concatenate([es.get(t, np.zeros(0, np.int64)), offset + idx])
        if es:
            m.element_sets[name] = es
    m.element_sets["all"] = {t: np.arange(len(c)) for t, c in m.cells.items()}
    for name, per_block in mesh.cell_data.items():  # fields such as per-element fibre orientation
        data = {}
        for b, t, _ in block_of:
            data.setdefault(t, []).append(np.asarray(per_block[b], float))
        try:
            m.cell_data[name] = {t: np.concatenate(v) for t, v in data.items()}
        except ValueError:  # blocks disagree on the component count: unusable as one field, reported if used
            continue
    return m


def centroids(X: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """(n_el, 3) mean of each element's distinct nodes (a collapsed hexahedron or a triangle written as a quad
    repeats a node, which a plain mean would count twice); X (n_node, 3), conn (n_el, k)."""
    c = np.sort(conn, axis=1)
    distinct = np.ones(c.shape, bool)
    distinct[:, 1:] = c[:, 1:] != c[:, :-1]
    return (X[c] * distinct[..., None]).sum(axis=1) / distinct.sum(axis=1)[:, None]


def add_box_sets(m: MeshArrays, node_boxes: dict, element_boxes: dict) -> None:
    """Add sets of nodes (by position) and elements (by centroid) inside boxes; empty sets are errors."""
    problems = []
    for name, spec in node_boxes.items():
        lo, hi = np.asarray(spec.box[0]) - spec.tolerance, np.asarray(spec.box[1]) + spec.tolerance
        sel = np.nonzero(np.all((m.X >= lo) & (m.X <= hi), axis=1))[0]
        if len(sel) == 0:
            problems.append((("mesh", "node_sets", name), f"box {list(map(list, spec.box))} holds no node"))
        m.node_sets[name] = sel
    for name, spec in element_boxes.items():
        lo, hi = np.asarray(spec.box[0]) - spec.tolerance, np.asarray(spec.box[1]) + spec.tolerance
        es = {}
        for t, conn in m.cells.items():
            c = centroids(m.X, conn)
            sel = np.nonzero(np.all((c >= lo) & (c <= hi), axis=1))[0]
            if len(sel):
                es[t] = sel
        if not es:
            problems.append((("mesh", "element_sets", name), f"box {list(map(list, spec.box))} holds no element"))
        m.element_sets[name] = es
    if problems:
        raise CompileError(problems)
