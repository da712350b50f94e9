"""Wrinkle indicator: how far each node of a surface stands off the smooth (locally quadratic) shape around it [mm].

Definition. For every node i of a surface node set, take the nodes of the set within a radius R of it in the
reference configuration (R a deck parameter, about the wavelength of the wrinkles to be caught). In the current configuration, build the local frame of that patch by principal
components (the normal is the direction of least spread of the patch's points), write every patch node as
(u, v, h) in that frame about node i, fit the quadric h = a0 + a1 u + a2 v + a3 u^2 + a4 u v + a5 v^2 by least
squares, and take |h_i - fit(0, 0)| = |a0| as node i's value.

Why. A smoothly doubly-curved part is, over a patch of radius R, its osculating quadric plus a remainder of order
R^4 / rho^3 (rho the smallest radius of curvature: for a sphere in its tangent frame h = r^2 / (2 rho) +
r^4 / (8 rho^3) + ...; a tilt of the frame by an angle of order R / rho adds a cubic of the same order), so it
scores about zero whatever its curvature; a wrinkle of amplitude A is mostly left out of the fit when its
wavelength is at most R, so a node on a crest or in a trough scores about A (between 0.8 A and 1.2 A, the fit's
side lobes; 1.00-1.02 A at a wavelength of R/2), while a wave of wavelength 2R, part of the shape, scores 0.2 A.
Take R about the wavelength of the wrinkles to be caught. The value is in mm, independent of the mesh size once
the patch holds enough nodes (at least 9; R of 1.5 element sizes or more, better 3 or more), and of rigid
motion. It is the two-dimensional, frame-free generalisation of ``surface_waviness`` (five nodes on a line of the
mesh, a parabola of one prescribed height component), for surfaces that turn in space during forming.
Limits: the neighbourhoods are fixed in the reference configuration (a patch shears with the fabric); a patch
more curved than a half sphere has no single-valued height and is not meaningful (R << rho is assumed).

Recorded: the largest value and the 99th percentile over the set (``<name>_max``, ``<name>_p99``) and over each
named region (``<name>_<region>_max``, ``<name>_<region>_p99``; a region is a node set, else the nodes of an
element set, intersected with the surface), and the per-node value as the frame point field ``wrinkle``
(NaN off the surface and at nodes whose patch is too small), per element as the cell field ``wrinkle_element``
(the largest value at its nodes; written by ``fdeck.run.Outputs``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from fdeck.compile.errors import CompileError
from fdeck.jit import njit_parallel, prange
from fdeck.registry import MeasureKind, register_measure

MIN_PATCH = 9  # nodes in a patch: 6 quadric coefficients plus a margin so that the fit does not interpolate


def patches(X: np.ndarray, nodes: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Neighbourhoods within ``radius`` [mm] in the reference configuration X (n_node, 3) among ``nodes`` (n_s,),
    as CSR: -> (ptr (n_s + 1,), members (ptr[-1],) node indices into X, sorted within each patch)."""
    lists = cKDTree(X[nodes]).query_ball_point(X[nodes], r=radius * (1 + 1e-9))
    ptr = np.zeros(len(nodes) + 1, np.int64)
    ptr[1:] = np.cumsum([len(li) for li in lists])
    members = np.concatenate([nodes[np.sort(li)] for li in lists]).astype(np.int64)
    return ptr, members


@njit_parallel
def residuals(x, centre, ptr, members, radius, out):
    """out (n_s,) <- |height - quadric fit| [mm] at each centre node (n_s,) in the configuration x (n_node, 3)
    (module docstring); ptr, members from ``patches``."""
    for s in prange(len(centre)):
        a, b = ptr[s], ptr[s + 1]
        k = b - a
        c = x[centre[s]].copy()
        mean = np.zeros(3)
        for j in range(a, b):
            for i in range(3):
                mean[i] += (x[members[j], i] - c[i]) / k
        cov = np.zeros((3, 3))
        for j in range(a, b):  # explicit loops: no temporary arrays per member
            for i in range(3):
                for l in range(3):
                    cov[i, l] += (x[members[j], i] - c[i] - mean[i]) * (x[members[j], l] - c[l] - mean[l])
        _, vec = np.linalg.eigh(cov)  # ascending eigenvalues: column 0 is the patch normal
        A = np.zeros((6, 6))
        rhs = np.zeros(6)
        row = np.empty(6)
        for j in range(a, b):
            d0, d1, d2 = x[members[j], 0] - c[0], x[members[j], 1] - c[1], x[members[j], 2] - c[2]
            u = (d0 * vec[0, 2] + d1 * vec[1, 2] + d2 * vec[2, 2]) / radius  # O(1): well-conditioned
            v = (d0 * vec[0, 1] + d1 * vec[1, 1] + d2 * vec[2, 1]) / radius
            h = d0 * vec[0, 0] + d1 * vec[1, 0] + d2 * vec[2, 0]
            row[0], row[1], row[2], row[3], row[4], row[5] = 1.0, u, v, u * u, u * v, v * v
            for i in range(6):
                rhs[i] += row[i] * h
                for l in range(6):
                    A[i, l] += row[i] * row[l]
        out[s] = abs(np.linalg.solve(A, rhs)[0])


class Measure:
    def __init__(self, card, nodes, ptr, members, regions, n_node):
        self.card, self.nodes, self.n_node = card, nodes, n_node
        ok = np.diff(ptr) >= MIN_PATCH  # smaller patches (corners of a coarse mesh) get NaN
        self.ok = np.nonzero(ok)[0]
        keep = np.concatenate([members[ptr[i]: ptr[i + 1]] for i in self.ok]) if len(self.ok) else members[:0]
        self.ptr = np.concatenate([[0], np.cumsum(np.diff(ptr)[ok])]).astype(np.int64)
        self.members = np.ascontiguousarray(keep, dtype=np.int64)
        self.centre = np.ascontiguousarray(nodes[ok], dtype=np.int64)
        self.regions = regions  # [(column prefix, positions (k,) into nodes)]
        self.columns = [c for prefix, _ in regions for c in (f"{prefix}_max", f"{prefix}_p99")]

    def values(self, x: np.ndarray) -> np.ndarray:
        """(n_s,) indicator per surface node [mm], NaN where the patch is too small."""
        out = np.full(len(self.nodes), np.nan)
        r = np.empty(len(self.centre))
        residuals(np.ascontiguousarray(x, dtype=np.float64), self.centre, self.ptr, self.members, self.card.radius, r)
        out[self.ok] = r
        return out

    def evaluate(self, x, v):
        r = self.values(x)
        row = []
        for _, pos in self.regions:
            vals = r[pos][np.isfinite(r[pos])]
            row += [float(vals.max()), float(np.percentile(vals, 99))] if len(vals) else [float("nan")] * 2
        return row

    def point_fields(self, x) -> dict[str, np.ndarray]:
        field = np.full(self.n_node, np.nan)
        field[self.nodes] = self.values(x)
        return {"wrinkle": field}


def _region_nodes(ctx, name: str, i: int) -> np.ndarray:
    if name in ctx.mesh.node_sets:
        return ctx.mesh.node_sets[name]
    if name in ctx.mesh.element_sets:
        return np.unique(np.concatenate([ctx.mesh.cells[t][e].ravel() for t, e in ctx.mesh.element_sets[name].items()]))
    raise CompileError([(ctx.path + ("regions", i), f"'{name}' is neither a node set nor an element set")])


def build(card, ctx):
    nodes = np.unique(ctx.node_set(card.nodes))
    ptr, members = patches(ctx.X, nodes, card.radius)
    most = int(np.diff(ptr).max())
    if most < MIN_PATCH:
        raise CompileError([(ctx.path + ("radius",), f"radius {card.radius} mm holds at most {most} nodes of "
                             f"'{card.nodes}' around a node; the quadric fit needs {MIN_PATCH} (take R of 1.5 "
                             "element sizes or more)")])
    regions = [(card.name, np.arange(len(nodes)))]
    for i, name in enumerate(card.regions):
        pos = np.nonzero(np.isin(nodes, _region_nodes(ctx, name, i)))[0]
        if not len(pos):
            raise CompileError([(ctx.path + ("regions", i), f"region '{name}' has no node of '{card.nodes}'")])
        regions.append((f"{card.name}_{name}", pos))
    return Measure(card, nodes, ptr, members, regions, len(ctx.X))


register_measure(MeasureKind("wrinkles", build))
