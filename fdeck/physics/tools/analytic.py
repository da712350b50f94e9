"""Analytic rigid surfaces: signed distance and outward normal of a point, as numba functions.

A surface is packed as ``(kind, params (8,))``: PLANE [px, py, pz, nx, ny, nz], SPHERE [cx, cy, cz, R],
CYLINDER [px, py, pz, ax, ay, az, R] with unit n and a. The distance is positive on the blank's side (outside the
sphere and the cylinder), and its gradient with respect to the point is the normal, so a penalty force p n is
-dE/dx of the energy E(-d) and the contact is conservative. A tool translated by u has the distance d(x - u).
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.jit import njit

PLANE, SPHERE, CYLINDER = 0, 1, 2


def pack(surface) -> tuple[int, np.ndarray]:
    """(kind, params (8,)) of a surface card (``fdeck.cards.contact.Plane`` / ``Sphere`` / ``Cylinder``)."""
    p = np.zeros(8)
    if surface.shape == "plane":
        n = np.asarray(surface.normal, float)
        p[:3], p[3:6] = surface.point, n / np.linalg.norm(n)
        return PLANE, p
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
    r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
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
