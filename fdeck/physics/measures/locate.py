"""Where a reference point lies in the mesh: the element holding it (or the nearest one) and its parent coordinates.

Used by the path tables (``output.paths``): a point given in the reference configuration is followed to the current
configuration through the isoparametric map of its element, x(p) = sum_a N_a(xi) x_a. Hexahedra (8 nodes, trilinear,
xi in [-1, 1]^3) and shell quadrilaterals (4 nodes, bilinear, xi in [-1, 1]^2; a triangle is a quadrilateral whose
last node repeats its third) are handled alike: xi minimises |X(xi) - p| over the parent element by Gauss-Newton
iterations clipped to the parent domain, so a point inside a hexahedron or on a shell's mid-surface is found exactly
(distance 0), and a point off the mesh maps to (about) its closest point on the nearest element.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from fdeck.physics.elements.hex8 import NODE_SIGNS
from fdeck.physics.elements.shell4 import SIGNS as QUAD_SIGNS

_CANDIDATES = 8  # nearest element centroids tried per point
_ITERATIONS = 12  # Gauss-Newton steps; the trilinear map of an undistorted element converges in 1-3


def shape(signs: np.ndarray, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Multilinear shape functions at parent points xi (m, d) for corner signs (k, d):
    -> N (m, k), dN/dxi (m, k, d)."""
    f = 1.0 + xi[:, None, :] * signs[None, :, :]  # (m, k, d) factors (1 + s_i xi_i)
    N = np.prod(f, axis=2) / 2.0 ** signs.shape[1]
    d = signs.shape[1]
    dN = np.empty(f.shape)
    for i in range(d):
        others = np.prod(np.delete(f, i, axis=2), axis=2)
        dN[:, :, i] = signs[None, :, i] * others / 2.0 ** d
    return N, dN


@dataclass
class Location:
    """Points located in the element groups: group (n,) index into the group list, element (n,) local index in that
    group, xi (n, 3) parent coordinates (unused third entry 0 on shells), distance (n,) [mm] from the point to its
    image in the element (0 inside)."""

    group: np.ndarray
    element: np.ndarray
    xi: np.ndarray
    distance: np.ndarray

    def current(self, groups: list, x: np.ndarray) -> np.ndarray:
        """(n, 3) images of the points in the configuration x (n_node, 3) [mm]."""
        out = np.empty((len(self.group), 3))
        for gi, g in enumerate(groups):
            sel = np.nonzero(self.group == gi)[0]
            if len(sel):
                signs = _signs(g)
                N, _ = shape(signs, self.xi[sel, : signs.shape[1]])
                out[sel] = np.einsum("mk,mkj->mj", N, x[g.conn[self.element[sel]]])
        return out


def _signs(g) -> np.ndarray:
    return NODE_SIGNS if g.conn.shape[1] == 8 else QUAD_SIGNS


def _closest(signs, Xe, p):
    """Clipped Gauss-Newton: Xe (m, k, 3) element nodes, p (m, 3) -> xi (m, d), distance (m,)."""
    m, d = len(p), signs.shape[1]
    xi = np.zeros((m, d))
    for _ in range(_ITERATIONS):
        N, dN = shape(signs, xi)
        r = p - np.einsum("mk,mkj->mj", N, Xe)
        J = np.einsum("mkj,mki->mji", Xe, dN)  # (m, 3, d) dX/dxi
        A = np.einsum("mji,mjl->mil", J, J)
        # a small Tikhonov term keeps the step finite where a degenerate (triangle) corner makes J rank-deficient
        A += 1e-12 * np.trace(A, axis1=1, axis2=2)[:, None, None] * np.eye(d)
        step = np.linalg.solve(A, np.einsum("mji,mj->mi", J, r)[..., None])[..., 0]
        xi = np.clip(xi + step, -1.0, 1.0)
    N, _ = shape(signs, xi)
    return xi, np.linalg.norm(p - np.einsum("mk,mkj->mj", N, Xe), axis=1)


def locate(groups: list, X: np.ndarray, points: np.ndarray) -> Location:
    """Locate reference points (n, 3) [mm] in the groups' elements (reference coordinates X (n_node, 3))."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    n = len(points)
    best = Location(np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros((n, 3)), np.full(n, np.inf))
    for gi, g in enumerate(groups):
        signs = _signs(g)
        centroids = X[g.conn].mean(axis=1)
        k = min(_CANDIDATES, len(centroids))
        _, cand = cKDTree(centroids).query(points, k=k)
        cand = np.asarray(cand).reshape(n, k)
        for j in range(k):
            el = cand[:, j]
            xi, dist = _closest(signs, X[g.conn[el]], points)
            better = dist < best.distance - 1e-12  # ties keep the earlier (group, candidate): deterministic
            best.group[better], best.element[better] = gi, el[better]
            best.xi[better] = 0.0
            best.xi[better, : signs.shape[1]] = xi[better]
            best.distance[better] = dist[better]
    return best
