"""Extruded rounded profile (``cards.contact.Profile``): the polyline's corners replaced by tangent circular arcs,
packed for ``tools.analytic.distance`` as straight segments and arcs in the profile's own (u, v) plane.

A corner P_k between unit directions t_in and t_out turns by phi (signed, positive to the left); its fillet of
radius r touches both segments at a distance r tan(|phi| / 2) from P_k, and its centre lies r from both, on the
inner side of the turn (the blank's side for a left turn). The signed distance of a point q (positive on the blank's
side, the left of the walk) is that of the nearest piece: a segment's by its left normal, an arc's as r - |q - c|
for a left turn and |q - c| - r for a right one, counted only where q lies in the arc's sector (elsewhere a
neighbouring segment is nearer). The profile is C1, so the nearest piece's sign is the surface's. Packed as
[origin (3), u (3), v (3), n_pieces, then 8 numbers per piece]: a segment [0, a_u, a_v, b_u, b_v, open_start,
open_end, 0] (open ends continue as straight lines), an arc [1, c_u, c_v, r, turn (+1 left, -1 right), t1_u, t1_v,
sweep half-angle cosine] with t1 the unit vector from the centre to the arc's midpoint.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.jit import njit

HEAD = 10  # origin, u, v, piece count
PIECE = 8


def pieces(points, radii) -> list[tuple]:
    """The profile's segments and arcs: [("line", a, b), ("arc", c, r, turn, mid, cos_half)] in walking order;
    raises ValueError (plain message) when a fillet does not fit its segments or a corner turns back on itself."""
    P = np.asarray(points, float)
    n = len(P)
    if isinstance(radii, (int, float)):
        radii = [float(radii)] * (n - 2)
    seg = np.diff(P, axis=0)
    length = np.linalg.norm(seg, axis=1)
    if np.any(length <= 0.0):
        raise ValueError(f"points {int(np.argmin(length)) + 1} and {int(np.argmin(length)) + 2} coincide")
    t = seg / length[:, None]
    crossing = _crossing(P, t)
    if crossing:
        raise ValueError(crossing)
    cut = np.zeros((n - 1, 2))  # length taken from each segment's start and end by the fillets
    arcs = []
    for k in range(1, n - 1):
        a, b = t[k - 1], t[k]
        phi = math.atan2(a[0] * b[1] - a[1] * b[0], float(a @ b))
        if abs(phi) > math.radians(179.0):
            raise ValueError(f"the profile turns back on itself at point {k + 1}")
        r = radii[k - 1]
        tan_len = r * math.tan(0.5 * abs(phi))
        cut[k - 1, 1], cut[k, 0] = tan_len, tan_len
        turn = 1.0 if phi >= 0.0 else -1.0
        left = np.array([-a[1], a[0]])
        start = P[k] - tan_len * a
        c = start + turn * r * left
        end = P[k] + tan_len * b
        mid = (start + end) / 2.0 - c
        mid = mid / np.linalg.norm(mid)  # not zero: a turn of 179 degrees or more was refused above
        arcs.append((c, r, turn, mid, math.cos(0.5 * abs(phi))))
    for k in range(n - 1):
        if cut[k].sum() > length[k] * (1.0 + 1e-12):
            raise ValueError(f"the fillets at the ends of segment {k + 1} (points {k + 1}-{k + 2}) need "
                             f"{cut[k].sum():.4g} mm of its {length[k]:.4g} mm: reduce their radii")
    out = []
    for k in range(n - 1):
        a, b = P[k] + cut[k, 0] * t[k], P[k + 1] - cut[k, 1] * t[k]
        whole = np.linalg.norm(b - a) <= 1e-12 * length[k]  # the fillets took the whole segment
        if whole and k == 0:  # an open end keeps its line: only its direction matters beyond the fillet
            a = b - t[k]
        elif whole and k == n - 2:
            b = a + t[k]
        if not whole or k in (0, n - 2):  # an inner segment taken whole leaves the two arcs meeting, tangent
            out.append(("line", a, b, k == 0, k == n - 2))
        if k < n - 2:
            out.append(("arc", *arcs[k]))
    return out


def _crossing(P: np.ndarray, t: np.ndarray) -> str:
    """A message when the polyline, its open ends continued as rays, crosses itself (the blank's side would then be
    both sides of the surface somewhere), else ""."""
    reach = 1e6 * (1.0 + float(np.abs(P).max()))  # a ray as a segment far beyond the profile
    ends = [[P[k].copy(), P[k + 1].copy()] for k in range(len(P) - 1)]
    ends[0][0] = P[0] - reach * t[0]
    ends[-1][1] = P[-1] + reach * t[-1]

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    for i in range(len(ends)):
        for j in range(i + 2, len(ends)):
            (a, b), (c, d) = ends[i], ends[j]
            if cross(a, b, c) * cross(a, b, d) < 0.0 and cross(c, d, a) * cross(c, d, b) < 0.0:
                return (f"the profile crosses itself: segments {i + 1} and {j + 1} (points {i + 1}-{i + 2} and "
                        f"{j + 1}-{j + 2}; the first and last continued beyond their end points)")
    return ""


def pack(surface) -> np.ndarray:
    """The packed parameters of a ``cards.contact.Profile`` (module docstring)."""
    u = np.asarray(surface.u_axis, float)
    u = u / np.linalg.norm(u)
    v = np.asarray(surface.v_axis, float)
    v = v - (v @ u) * u
    v = v / np.linalg.norm(v)
    parts = pieces(surface.points, surface.radii)
    p = np.zeros(HEAD + PIECE * len(parts))
    p[0:3], p[3:6], p[6:9], p[9] = surface.origin, u, v, len(parts)
    for i, part in enumerate(parts):
        o = HEAD + PIECE * i
        if part[0] == "line":
            _, a, b, open_start, open_end = part
            p[o:o + 7] = 0.0, a[0], a[1], b[0], b[1], float(open_start), float(open_end)
        else:
            _, c, r, turn, mid, cos_half = part
            p[o:o + 8] = 1.0, c[0], c[1], r, turn, mid[0], mid[1], cos_half
    return p


@njit
def distance(p, x0, x1, x2):
    """(d [mm], n0, n1, n2): signed distance of the point to the profile surface and the outward unit normal."""
    r0, r1, r2 = x0 - p[0], x1 - p[1], x2 - p[2]
    qu = r0 * p[3] + r1 * p[4] + r2 * p[5]
    qv = r0 * p[6] + r1 * p[7] + r2 * p[8]
    best, d_best, nu, nv = math.inf, 0.0, 0.0, 1.0
    for i in range(int(p[9])):
        o = HEAD + PIECE * i
        if p[o] == 0.0:
            au, av, bu, bv = p[o + 1], p[o + 2], p[o + 3], p[o + 4]
            eu, ev = bu - au, bv - av
            L = math.sqrt(eu * eu + ev * ev)
            tu, tv = eu / L, ev / L
            s = (qu - au) * tu + (qv - av) * tv
            side = tu * (qv - av) - tv * (qu - au)  # along the left normal (-tv, tu)
            if (s >= 0.0 or p[o + 5] != 0.0) and (s <= L or p[o + 6] != 0.0):
                # the foot lies on the piece (or on an open end's continuation): the line's own distance and
                # normal, not the foot vector, whose part along the line is round-off
                if abs(side) < best:
                    best, d_best, nu, nv = abs(side), side, -tv, tu
                continue
            s = 0.0 if s < 0.0 else L  # beyond a closed end: towards that end point
            fu, fv = qu - (au + s * tu), qv - (av + s * tv)
            dist = math.sqrt(fu * fu + fv * fv)
            if dist < best:
                sign = 1.0 if side >= 0.0 else -1.0
                best, d_best = dist, sign * dist
                nu, nv = (sign * fu / dist, sign * fv / dist) if dist > 0.0 else (-tv, tu)
        else:
            cu, cv, r, turn = p[o + 1], p[o + 2], p[o + 3], p[o + 4]
            du, dv = qu - cu, qv - cv
            L = math.sqrt(du * du + dv * dv)
            # the centre itself, or outside the arc's sector (its edges included, by a round-off margin: where two
            # arcs meet with no line between them, a point on their common radius belongs to both)
            if L == 0.0 or (du * p[o + 5] + dv * p[o + 6]) < L * (p[o + 7] - 1e-12):
                continue
            dist = abs(L - r)
            if dist < best:
                best = dist
                d_best = turn * (r - L)
                nu, nv = -turn * du / L, -turn * dv / L
    return (d_best, nu * p[3] + nv * p[6], nu * p[4] + nv * p[7], nu * p[5] + nv * p[8])


def facets(p: np.ndarray, extent: np.ndarray, per_arc: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """(points, triangles) of the profile over the blank's span along the extrusion (``extent`` lo (3,), hi (3,)),
    its open ends drawn 0.25 of the blank's diagonal beyond their end points; display only."""
    o, u, v = p[0:3], p[3:6], p[6:9]
    w = np.cross(u, v)
    lo, hi = extent[:3], extent[3:]
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]) - o
    grow = 0.25 * max(float(np.linalg.norm(hi - lo)), 1.0)
    span = ((corners @ w).min() - grow, (corners @ w).max() + grow)
    curve = []
    for i in range(int(p[9])):
        q = p[HEAD + PIECE * i:HEAD + PIECE * (i + 1)]
        if q[0] == 0.0:
            a, b = q[1:3].copy(), q[3:5].copy()
            t = (b - a) / np.linalg.norm(b - a)
            if q[5]:
                a = a - grow * t
            if q[6]:
                b = b + grow * t
            curve += [a, b]
        else:
            c, r, turn, mid, half = q[1:3], q[3], q[4], q[5:7], math.acos(min(1.0, q[7]))
            base = math.atan2(mid[1], mid[0])
            for ang in np.linspace(-half, half, per_arc + 1)[1:-1] * turn:
                curve.append(c + r * np.array([math.cos(base + ang), math.sin(base + ang)]))
    curve = np.array(curve)
    m = len(curve)
    P = np.concatenate([o + np.outer(curve[:, 0], u) + np.outer(curve[:, 1], v) + s * w for s in span])
    T = []
    for k in range(m - 1):  # the walk's left (the blank's side) is +normal: triangles turn counter-clockwise there
        T += [[k, k + m + 1, k + 1], [k, k + m, k + m + 1]]
    return P, np.array(T)
