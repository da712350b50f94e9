"""Analytic rigid surfaces: signed distance and outward normal of a point, as numba functions.

A surface is packed as ``(kind, params (8,))``: PLANE [px, py, pz, nx, ny, nz], SPHERE [cx, cy, cz, R],
CYLINDER [px, py, pz, ax, ay, az, R] with unit n and a, ROUNDED_BOX [cx, cy, cz, bx, by, bz, R] (half-sizes b
including the rounding R: the box shrunk by R, grown again by a distance R, so its distance is that of the sharp
inner box less R), PROFILE (``tools.profile``: a rounded polyline extruded, a longer array). The distance is
positive on the blank's side (outside the
sphere and the cylinder), and its gradient with respect to the point is the normal, so a penalty force p n is
-dE/dx of the energy E(-d) and the contact is conservative. A tool translated by u has the distance d(x - u).
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.jit import njit
from fdeck.physics.tools import profile

PLANE, SPHERE, CYLINDER, ROUNDED_BOX, PROFILE = 0, 1, 2, 3, 4


def pack(surface) -> tuple[int, np.ndarray]:
    """(kind, params) of a surface card (``fdeck.cards.contact.Plane`` / ``Sphere`` / ``Cylinder`` / ``RoundedBox``:
    params (8,); ``Profile``: ``profile.pack``'s longer array)."""
    if surface.shape == "profile":
        return PROFILE, profile.pack(surface)
    p = np.zeros(8)
    if surface.shape == "plane":
        n = np.asarray(surface.normal, float)
        p[:3], p[3:6] = surface.point, n / np.linalg.norm(n)
        return PLANE, p
    if surface.shape == "rounded_box":
        p[:3], p[3:6], p[6] = surface.centre, surface.half_size, surface.radius
        return ROUNDED_BOX, p
    if surface.shape == "sphere":
        p[:3], p[3] = surface.centre, surface.radius
        return SPHERE, p
    a = np.asarray(surface.axis, float)
    p[:3], p[3:6], p[6] = surface.point, a / np.linalg.norm(a), surface.radius
    return CYLINDER, p


@njit
def distance(kind, p, x0, x1, x2):
    """(d [mm], n0, n1, n2) of the point (x0, x1, x2) in the tool's frame: signed distance and outward unit normal."""
    if kind == PLANE:
        n0, n1, n2 = p[3], p[4], p[5]
        return (x0 - p[0]) * n0 + (x1 - p[1]) * n1 + (x2 - p[2]) * n2, n0, n1, n2
    if kind == PROFILE:
        return profile.distance(p, x0, x1, x2)
    r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
    if kind == ROUNDED_BOX:
        return _box(r0, r1, r2, p[3] - p[6], p[4] - p[6], p[5] - p[6], p[6])
    if kind == CYLINDER:
        s = r0 * p[3] + r1 * p[4] + r2 * p[5]
        r0, r1, r2 = r0 - s * p[3], r1 - s * p[4], r2 - s * p[5]
        radius = p[6]
    else:
        radius = p[3]
    L = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if L == 0.0:  # on the centre (axis): any direction is a normal; take the first axis not along the cylinder's
        return -radius, 1.0, 0.0, 0.0
    return L - radius, r0 / L, r1 / L, r2 / L


@njit
def _box(r0, r1, r2, b0, b1, b2, radius):
    """Distance and normal of a box of half-sizes (b0, b1, b2) about the origin, grown by ``radius``."""
    q0, q1, q2 = abs(r0) - b0, abs(r1) - b1, abs(r2) - b2
    s0 = 1.0 if r0 >= 0.0 else -1.0
    s1 = 1.0 if r1 >= 0.0 else -1.0
    s2 = 1.0 if r2 >= 0.0 else -1.0
    if q0 > 0.0 or q1 > 0.0 or q2 > 0.0:  # outside the inner box: towards its nearest point
        o0, o1, o2 = max(q0, 0.0), max(q1, 0.0), max(q2, 0.0)
        L = math.sqrt(o0 * o0 + o1 * o1 + o2 * o2)
        return L - radius, s0 * o0 / L, s1 * o1 / L, s2 * o2 / L
    if q0 >= q1 and q0 >= q2:  # inside: through the nearest face
        return q0 - radius, s0, 0.0, 0.0
    if q1 >= q2:
        return q1 - radius, 0.0, s1, 0.0
    return q2 - radius, 0.0, 0.0, s2


def facets(kind: int, p: np.ndarray, extent: np.ndarray, n: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """(points (m, 3), triangles (k, 3)) showing the surface in the frames, outward by the right-hand rule: a plane
    as a square 1.5 times the blank's diagonal about the blank's centre (``extent`` = lo (3,), hi (3,) of the
    blank), a sphere by n x n/2 facets, a cylinder by n facets around over the blank's span along its axis, a
    rounded box as its sharp box (for display only: the contact uses the exact distance)."""
    if kind == PROFILE:
        return profile.facets(p, extent)
    lo, hi = extent[:3], extent[3:]
    centre, size = 0.5 * (lo + hi), 1.5 * max(float(np.linalg.norm(hi - lo)), 1.0)
    if kind == PLANE:
        nrm = p[3:6]
        a = np.cross(nrm, [1.0, 0.0, 0.0] if abs(nrm[0]) < 0.9 else [0.0, 1.0, 0.0])
        a /= np.linalg.norm(a)
        b = np.cross(nrm, a)
        c = centre - np.dot(centre - p[:3], nrm) * nrm
        P = np.array([c + 0.5 * size * (sa * a + sb * b) for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        return P, np.array([[0, 1, 2], [0, 2, 3]])
    if kind == ROUNDED_BOX:
        sgn = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], float)
        P = p[:3] + sgn * p[3:6]
        quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
        return P, np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])
    if kind == SPHERE:
        th = np.linspace(0.0, np.pi, n // 2 + 1)
        axis, radius, span = np.array([0.0, 0.0, 1.0]), p[3], None
    else:
        axis, radius = p[3:6], p[6]
        s = (np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
             - p[:3]) @ axis
        span = (s.min() - 0.25 * size, s.max() + 0.25 * size)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)
    ph = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    if span is None:  # sphere: rings from pole to pole (poles repeated per meridian: simple, display only)
        ring = [p[:3] + radius * (np.cos(t) * axis + np.sin(t) * (np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None]
                                                                  * e2)) for t in th]
    else:
        ring = [p[:3] + s * axis + radius * (np.cos(ph)[:, None] * e1 + np.sin(ph)[:, None] * e2) for s in span]
    P = np.concatenate(ring)
    T = []
    for r in range(len(ring) - 1):
        for k in range(n):
            a, b = r * n + k, r * n + (k + 1) % n
            T += [[a, a + n, b + n], [a, b + n, b]] if span is None else [[a, b, b + n], [a, b + n, a + n]]
    return P, np.array(T)
