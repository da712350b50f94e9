"""Local fibre bending stiffness of hexahedral fabric sections ([B] cure 2, MODELS.md section 4), a section add-on.

Why: a hyperelastic continuum of fibres has no bending stiffness of its own fibres; with transverse shear three to
four orders softer than fibre tension, 8-node hexahedra develop transverse zig-zag modes in bending ([B]). This
effect adds the fibres' own bending energy, computed from the positions of neighbouring elements as rotation-free
shells do (no rotational dofs).

What M is. ``M(chi)`` is the bending moment per unit width [N mm / mm = N] of a fabric specimen of thickness
``thickness`` = T [mm] bent to the curvature chi [1/mm] of one fibre family: what a cantilever (Peirce) or
three-point bending test of the fabric gives once divided by the specimen width. The effect spreads it through the
section as the energy density w(chi) / T [MPa = mJ/mm^3] with w(chi) = int_0^chi M dchi [mJ/mm^2], so a sheet of
thickness T bent uniformly to chi stores w(chi) per unit area, whatever the number of elements through its
thickness. The law is odd in chi: M = D1 chi + D2 chi^3, or a table of (chi, M) points interpolated linearly.

Kinematics (per section, in the reference fibre frame f1 warp, f2 weft, f3 thickness of each element):

* Two levels per element through its thickness, at the Gauss abscissae -1/sqrt(3), +1/sqrt(3) of the natural
  coordinate closest to f3 ([B]: W = sum_a M chi* A(s_a) J_s). At each level the element's section carries the
  current fibre tangents t_i = F f_i (i = warp, weft; F at the level point, linear in the element's 8 nodes) and the
  unit section normal n = t_1 x t_2 / |t_1 x t_2|.
* Neighbours along fibre i are the elements across the two faces whose reference outward normals are closest to
  +f_i and -f_i. Each pair of neighbours (l, r) shares a *hinge* at every level. Its curvature is the bending
  angle between the two sections' fibre tangents over the reference distance L of their level points:
      chi = 2 asin(s / 2) / L - chi_0,   s = nbar . (u_r - u_l),   u = t_i / |t_i|,   nbar = unit(n_l + n_r),
  i.e. the rotation of the fibre about the in-plane axis normal to it (out-of-plane bending), exact for a
  circular arc. chi_0 is its value in the reference configuration (zero on a flat blank). chi > 0 when the fibre
  turns towards the +f3 side (centre of curvature on that side). Rigid motions leave every chi unchanged; any
  homogeneous deformation gives equal tangents, hence chi = chi_0.
* In-plane bending (``in_plane`` laws, optional): hinges between the same neighbours whose curvature is the
  rotation of the fibre about the section normal,
      chi = asin(s) / L - chi_0,   s = nbar . (u_l x u_r),
  exact for an arc in the fabric's plane, positive when the fibre turns counter-clockwise about nbar. Valid for a
  kink below 90 deg per hinge: asin's slope grows without bound there and beyond it the measured angle falls again
  (atan2 of the sine and the cosine u_l . u_r would hold to 180 deg; not done, the bands measured are 20-46 deg
  spread over several hinges). A jump of
  shear angle across a fibre line kinks the other family's fibres in the plane, so this energy gives such jumps
  (and the element-scale shear bands of forming) a width set by the ratio of the in-plane bending rigidity to the
  shear stiffness: the second-gradient energy of Ferretti et al. 2014 and Barbagallo et al. 2017, discretised
  like the out-of-plane one. Twist is not modelled.
* Energy: W = sum over hinges and levels of w(chi) V_h / T, with V_h = (V_l,a + V_r,a) / 2 (V_e,a the reference
  volume of the element's half on the level's side): every element lends half of each level's volume to each of
  its two hinges per family, so a uniformly bent sheet stores w(chi) per unit area. The forces are the exact
  derivative dW/dx (chain rule through s, nbar and both normals, see ``hinges``), so the energy ledger closes.
* Why hinges and not one constant curvature per element: the constant curvature of an element averaged over its
  two sides cancels for a period-2 zig-zag (both side angles have opposite signs), which is exactly the spurious
  mode to suppress; per hinge the zig-zag costs (2 alpha / L)^2 at every hinge.
* Free edges: an element without a neighbour on one side has no hinge there, so the moment vanishes at a free
  edge, as at the free end of a beam; its half-volume on that side stores no bending energy. The same holds at a
  clamped face: fixing one node plane leaves the first element's fibre tangent free to turn, so to hold the fibres'
  rotation too, fix the nodes of the first element column (two node planes). Elements outside the section
  (another section, another element group) are not neighbours: the effect works on its own group only.
* The mesh must be fibre-aligned: every element needs faces whose normals lie within ``ALIGN_DEG`` of +-f_i for
  the bending families and a natural axis within ``ALIGN_DEG`` of f3; otherwise a CompileError names the elements.

Stable step: the bending stiffness enters the time step. For each hinge-level the Gauss-Newton stiffness is
k g g^T with k = (M'(chi) + |M| L) V_h / T and g = dchi/dx; the geometric part M d2chi/dx2 is smaller by about
|M| L / M' (the hinge angle for a linear law) and is covered by the |M| L term. A block Gershgorin bound of
M^-1 K (lumped masses) gives omega^2 <= max_n (1/m_n) sum_h k_h |g_h,n| sum_m |g_h,m|: exact for the zig-zag of a
uniform 1-D chain, 0.8 of the exact critical step on the plates of the tests. Per element, the largest bending
omega_b^2 of its nodes is added to the element's own omega_g = 2 / dt_group (the two stiffnesses add, so do
their squared frequencies), and the effect reports min_e 2 / sqrt(omega_b^2 + omega_g^2).

References (formulations used, by reference): E. Onate, F. Zarate, Rotation-free triangular plate and shell
elements, IJNME 47 (2000) (BST: curvature from neighbouring elements' positions); F.G. Flores and E. Onate's
large-strain extensions of the BST triangle (2005); E. Grinspun et al., Discrete shells, SCA 2003 (bending energy per
hinge from the angle across shared edges); P. Boisse, S. Mathieu, N. Hamila, ECCM17 2016 [B] and S. Mathieu et al.
(2015, 2016): local fibre bending stiffness for 3D interlocks on hexahedra, two levels through the thickness;
M. Ferretti, A. Madeo, F. dell'Isola, P. Boisse, Modeling the onset of shear boundary layers in fibrous composite
reinforcements by second-gradient theory, ZAMP 65 (2014), and G. Barbagallo, A. Madeo, I. Azehaf, I. Giorgio,
F. Morestin, P. Boisse, Bias extension test on an unbalanced woven composite reinforcement: experiments and
modeling via a second-gradient continuum approach, J. Compos. Mater. 51 (2017): in-plane fibre bending (second
gradient) in fabric forming.

Shapes: x (n_node, 3) [mm]; per element e, level a in {0 lower, 1 upper} (along f3), family i in {0 warp, 1 weft}:
G (n_el, 2, 2, 8) dN_n/dX . f_i at the level point [1/mm]; per hinge h (family fam, mode 0 out of plane or 1 in
plane): chi (n_h, 2) [1/mm], M (n_h, 2) [N].
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import STORED, Term
from fdeck.engine.gather import gather_add, node_slots
from fdeck.jit import njit, njit_parallel, prange
from fdeck.registry import EffectKind, register_effect
from fdeck.cards.fibre_bending import MAX_TABLE, BendingLaw, FibreBending


LAW_SIZE = 4 + 3 * MAX_TABLE
"""Packed law: [kind (0 polynomial, 1 table), D1, D2, n_points, chi[16], M[16], w[16]] (w = energy at each chi)."""

ALIGN_DEG = 35.0
"""Largest angle [deg] between a fibre direction and the normal of the element face taken as its neighbour side
(and between f3 and the natural axis taken as the thickness): beyond it the mesh is not fibre-aligned."""

FAMILIES = ("warp", "weft")


# ------------------------------------------------------------------------------------------------------------------
# Card
# ------------------------------------------------------------------------------------------------------------------







def pack_law(law: BendingLaw) -> np.ndarray:
    """(LAW_SIZE,) float64 parameters of one family's law (see ``LAW_SIZE``)."""
    p = np.zeros(LAW_SIZE)
    if law.table is None:
        p[0:3] = 0.0, law.D1, law.D2
        return p
    chi = np.array([c for c, _ in law.table])
    m = np.array([v for _, v in law.table])
    w = np.concatenate([[0.0], np.cumsum(0.5 * (m[1:] + m[:-1]) * np.diff(chi))])  # exact for linear M
    n = len(chi)
    p[0], p[3] = 1.0, n
    p[4:4 + n], p[4 + MAX_TABLE:4 + MAX_TABLE + n], p[4 + 2 * MAX_TABLE:4 + 2 * MAX_TABLE + n] = chi, m, w
    return p


@njit
def bending_law(chi, p):
    """(M [N], w [mJ/mm^2], dM/dchi [N mm]) at curvature chi [1/mm] for packed parameters p (LAW_SIZE,)."""
    a = abs(chi)
    sign = 1.0 if chi >= 0.0 else -1.0
    if p[0] == 0.0:
        d1, d2 = p[1], p[2]
        return sign * (d1 * a + d2 * a * a * a), 0.5 * d1 * a * a + 0.25 * d2 * a * a * a * a, d1 + 3.0 * d2 * a * a
    n = int(p[3])
    k = n - 2  # beyond the last point: the last segment's slope
    for j in range(n - 1):
        if a < p[5 + j]:
            k = j
            break
    c0, m0 = p[4 + k], p[4 + MAX_TABLE + k]
    slope = (p[4 + MAX_TABLE + k + 1] - m0) / (p[5 + k] - c0)
    da = a - c0
    return sign * (m0 + slope * da), p[4 + 2 * MAX_TABLE + k] + m0 * da + 0.5 * slope * da * da, slope


# ------------------------------------------------------------------------------------------------------------------
# Reference geometry (NumPy, once per build)
# ------------------------------------------------------------------------------------------------------------------

class MeshNotAligned(ValueError):
    """The mesh is not fibre-aligned: ``what`` says how, ``local`` (array) which elements (group-local indices)."""

    def __init__(self, what: str, local: np.ndarray):
        self.what, self.local = what, local
        super().__init__(f"{len(local)} elements {what}")


def thickness_axis(X: np.ndarray, conn: np.ndarray, frame: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Natural axis of each element closest to f3, its sign along f3 and the cosine of their angle.

    X (n_node, 3), conn (n_el, 8), frame (n_el, 3, 3). Returns k (n_el,) in {0, 1, 2}, sigma (n_el,) +-1, cos (n_el,).
    """
    from fdeck.physics.elements.hex8 import shape_gradients_local

    dxi = shape_gradients_local(np.zeros((1, 3)))[0]  # (8, 3) at the centre
    g = np.einsum("eai,aj->eji", X[conn], dxi)  # (n_el, 3 natural axes, 3) covariant base vectors
    proj = np.einsum("eji,ei->ej", g, frame[:, 2]) / np.linalg.norm(g, axis=2)
    k = np.argmax(np.abs(proj), axis=1)
    c = proj[np.arange(len(k)), k]
    return k, np.sign(c), np.abs(c)


def level_geometry(X: np.ndarray, conn: np.ndarray, frame: np.ndarray) -> dict:
    """Per element and level: G (n_el, 2, 2, 8) = dN_n/dX . f_i [1/mm], reference level points P (n_el, 2, 3) [mm],
    level half-volumes V (n_el, 2) [mm^3]. Raises MeshNotAligned if no natural axis is close to f3."""
    from fdeck.physics.elements.hex8 import NODE_SIGNS, prepare, shape_gradients_local

    n_el = len(conn)
    k, sigma, cos = thickness_axis(X, conn, frame)
    bad = cos < math.cos(math.radians(ALIGN_DEG))
    if bad.any():
        raise MeshNotAligned(f"have no edge direction within {ALIGN_DEG:g} deg of the thickness direction f3",
                             np.nonzero(bad)[0])
    pts = np.zeros((n_el, 2, 3))
    pts[np.arange(n_el), 0, k] = -sigma / math.sqrt(3.0)
    pts[np.arange(n_el), 1, k] = sigma / math.sqrt(3.0)
    dxi = shape_gradients_local(pts.reshape(-1, 3)).reshape(n_el, 2, 8, 3)
    N = np.prod(1.0 + NODE_SIGNS[None, None] * pts[:, :, None, :], axis=3) / 8.0  # (n_el, 2, 8)
    xe = X[conn]
    J = np.einsum("eni,elnj->elij", xe, dxi)  # dX_i / dxi_j at the level points
    dNdX = np.einsum("elnj,elji->elni", dxi, np.linalg.inv(J))  # (n_el, 2, 8, 3)
    G = np.einsum("elni,efi->elfn", dNdX, frame[:, :2])  # (n_el, 2 levels, 2 families, 8)
    P = np.einsum("eln,eni->eli", N, xe)
    w = prepare(X, conn)["w"]  # (n_el, 8) volumes of the 2x2x2 Gauss points (same order as NODE_SIGNS)
    upper = NODE_SIGNS[:, k].T * sigma[:, None] > 0  # (n_el, 8)
    V = np.stack([np.where(upper, 0.0, w).sum(axis=1), np.where(upper, w, 0.0).sum(axis=1)], axis=1)
    return dict(G=np.ascontiguousarray(G), P=P, V=V)


def face_twins(conn: np.ndarray) -> np.ndarray:
    """(n_el, 6) index e' * 6 + f' of the face shared with another element of conn (n_el, 8), or -1."""
    from fdeck.physics.elements.hex8 import FACES

    keys = np.sort(conn[:, FACES], axis=2).reshape(-1, 4)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    twin = np.full(len(keys), -1, np.int64)
    same = inv[order[1:]] == inv[order[:-1]]
    a, b = order[:-1][same], order[1:][same]
    twin[a], twin[b] = b, a
    return twin.reshape(-1, 6)


def outward_face_normals(X: np.ndarray, conn: np.ndarray) -> np.ndarray:
    """(n_el, 6, 3) unit outward normals of the faces (order hex8.FACES) in the reference configuration."""
    from fdeck.physics.elements.hex8 import FACES

    f = X[conn[:, FACES]]  # (n_el, 6, 4, 3)
    n = np.cross(f[:, :, 2] - f[:, :, 0], f[:, :, 3] - f[:, :, 1])
    out = f.mean(axis=2) - X[conn].mean(axis=1)[:, None, :]
    n *= np.sign(np.einsum("efi,efi->ef", n, out))[..., None]
    size = np.linalg.norm(n, axis=2, keepdims=True)
    return n / np.where(size > 0, size, 1.0)  # a collapsed face (zero area) gets a zero normal


def fibre_neighbours(X: np.ndarray, conn: np.ndarray, frame: np.ndarray, family: int) -> np.ndarray:
    """(n_el, 2) neighbour across the face closest to -f_i (column 0) and +f_i (column 1), -1 at a free edge.

    Raises MeshNotAligned when a face normal is farther than ALIGN_DEG from +-f_i, or when two neighbours disagree
    (e's + neighbour does not have e as its - neighbour). An element with a collapsed face (the half-diamonds of
    ``mesh.block.lattice: diagonal``, a prism) has one face along each fibre family; its other side is the block's
    side, which it takes as a free edge."""
    from fdeck.physics.elements.hex8 import prisms

    nf = outward_face_normals(X, conn)
    c = np.einsum("efi,ei->ef", nf, frame[:, family])
    plus, minus = np.argmax(c, axis=1), np.argmin(c, axis=1)
    rows = np.arange(len(conn))
    lim = math.cos(math.radians(ALIGN_DEG))
    prism = prisms(conn)
    no_plus, no_minus = c[rows, plus] < lim, -c[rows, minus] < lim
    bad = (no_plus | no_minus) & ~(prism & (no_plus != no_minus))
    name = FAMILIES[family]
    if bad.any():
        raise MeshNotAligned(f"have no pair of faces normal to {name} within {ALIGN_DEG:g} deg: fibre_bending "
                             "needs a mesh with element edges along the fibres", np.nonzero(bad)[0])
    twin = face_twins(conn)
    nb = np.stack([np.where(no_minus, -1, twin[rows, minus]), np.where(no_plus, -1, twin[rows, plus])], axis=1)
    nb = np.where(nb >= 0, nb // 6, -1)
    right = nb[:, 1]
    has = right >= 0
    wrong = has & (nb[np.where(has, right, 0), 0] != rows)
    if wrong.any():
        raise MeshNotAligned(f"are not the {name}- neighbour of their {name}+ neighbour: the fibre direction "
                             "turns too much between neighbouring elements", np.nonzero(wrong)[0])
    return nb


# ------------------------------------------------------------------------------------------------------------------
# Kernels
# ------------------------------------------------------------------------------------------------------------------

@njit
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit
def _perp(u0, u1, u2, v0, v1, v2, scale):
    """(I - u u^T) v * scale, u a unit vector."""
    d = u0 * v0 + u1 * v1 + u2 * v2
    return (v0 - d * u0) * scale, (v1 - d * u1) * scale, (v2 - d * u2) * scale


@njit_parallel
def tangents(x, conn, G, t, nrm, cn):
    """Fibre tangents t (n_el, 2, 2, 3) = F f_i at each level [-], unit section normals nrm (n_el, 2, 3) and
    |t_warp x t_weft| cn (n_el, 2)."""
    for e in prange(conn.shape[0]):
        for a in range(2):
            for i in range(2):
                s0 = 0.0
                s1 = 0.0
                s2 = 0.0
                for n in range(8):
                    g = G[e, a, i, n]
                    node = conn[e, n]
                    s0 += g * x[node, 0]
                    s1 += g * x[node, 1]
                    s2 += g * x[node, 2]
                t[e, a, i, 0] = s0
                t[e, a, i, 1] = s1
                t[e, a, i, 2] = s2
            c0, c1, c2 = _cross(t[e, a, 0, 0], t[e, a, 0, 1], t[e, a, 0, 2], t[e, a, 1, 0], t[e, a, 1, 1],
                                t[e, a, 1, 2])
            c = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
            cn[e, a] = c
            nrm[e, a, 0] = c0 / c
            nrm[e, a, 1] = c1 / c
            nrm[e, a, 2] = c2 / c


@njit
def _side_adjoint(t, nrm, cn, e, a, fam, q0, q1, q2, inv_t, b0, b1, b2, adj, dchi, h, side, scale, dchids):
    """ds/dt_j of one side's tangents (j = warp, weft): through its normal (p = (I - n n) q / |c|, q = ds/dn) and,
    for the hinge's family, through its unit tangent ((I - u u) b / |t|, b = ds/du). Stores scale * ds/dt in adj
    and dchids * |ds/dt| in dchi."""
    n0, n1, n2 = nrm[e, a, 0], nrm[e, a, 1], nrm[e, a, 2]
    p0, p1, p2 = _perp(n0, n1, n2, q0, q1, q2, 1.0 / cn[e, a])
    # d(p . t_0 x t_1) = dt_0 . (t_1 x p) + dt_1 . (p x t_0)
    w0 = _cross(t[e, a, 1, 0], t[e, a, 1, 1], t[e, a, 1, 2], p0, p1, p2)
    w1 = _cross(p0, p1, p2, t[e, a, 0, 0], t[e, a, 0, 1], t[e, a, 0, 2])
    u0, u1, u2 = t[e, a, fam, 0] * inv_t, t[e, a, fam, 1] * inv_t, t[e, a, fam, 2] * inv_t
    f0, f1, f2 = _perp(u0, u1, u2, b0, b1, b2, inv_t)
    for j in range(2):
        v0, v1, v2 = (w0[0], w0[1], w0[2]) if j == 0 else (w1[0], w1[1], w1[2])
        if j == fam:
            v0 += f0
            v1 += f1
            v2 += f2
        adj[h, a, side, j, 0] = scale * v0
        adj[h, a, side, j, 1] = scale * v1
        adj[h, a, side, j, 2] = scale * v2
        dchi[h, a, side, j] = dchids * math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)


@njit_parallel
def hinges(t, nrm, cn, left, right, fam, mode, L, V, chi0, laws, inv_T, Gsum, chi, moment, energy, adj, dchi, kS):
    """Curvature, moment, energy and energy adjoints of every hinge h (n_h,) at both levels.

    Inputs: t, nrm, cn from ``tangents``; left, right, fam, mode (n_h,) elements, family and mode (0 out of
    plane, 1 in plane); L, V, chi0 (n_h, 2) reference distance [mm], volume [mm^3], reference curvature [1/mm];
    laws (4, LAW_SIZE), row fam + 2 mode; inv_T = 1/T [1/mm]; Gsum (n_el, 2, 2) = sum_n |G|. Outputs: chi, moment
    (n_h, 2) [1/mm], [N]; energy (n_h,) [mJ]; adj (n_h, 2, 2 sides, 2 tangents, 3) = dW/dt [N mm];
    dchi (n_h, 2, 2, 2) = |dchi/dt| [1/mm]; kS (n_h, 2) = k_h sum_m |g_h,m| for the stable step [N/mm].
    """
    for h in prange(left.shape[0]):
        l, r, i = left[h], right[h], fam[h]
        e_h = 0.0
        for a in range(2):
            tl = math.sqrt(t[l, a, i, 0] ** 2 + t[l, a, i, 1] ** 2 + t[l, a, i, 2] ** 2)
            tr = math.sqrt(t[r, a, i, 0] ** 2 + t[r, a, i, 1] ** 2 + t[r, a, i, 2] ** 2)
            ul0, ul1, ul2 = t[l, a, i, 0] / tl, t[l, a, i, 1] / tl, t[l, a, i, 2] / tl
            ur0, ur1, ur2 = t[r, a, i, 0] / tr, t[r, a, i, 1] / tr, t[r, a, i, 2] / tr
            m0, m1, m2 = nrm[l, a, 0] + nrm[r, a, 0], nrm[l, a, 1] + nrm[r, a, 1], nrm[l, a, 2] + nrm[r, a, 2]
            mn = math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
            nb0, nb1, nb2 = m0 / mn, m1 / mn, m2 / mn
            if mode[h] == 0:
                # out of plane: s = nbar . (u_r - u_l) = 2 sin(angle / 2), chi = 2 asin(s / 2) / L
                d0, d1, d2 = ur0 - ul0, ur1 - ul1, ur2 - ul2
                half = 0.5 * (nb0 * d0 + nb1 * d1 + nb2 * d2)
                c = 2.0 * math.asin(half) / L[h, a] - chi0[h, a]
                dchids = 1.0 / (L[h, a] * math.sqrt(1.0 - half * half))
                bl0, bl1, bl2 = -nb0, -nb1, -nb2  # ds/du_l
                br0, br1, br2 = nb0, nb1, nb2  # ds/du_r
            else:
                # in plane: s = nbar . (u_l x u_r) = sin(angle about nbar), chi = asin(s) / L
                d0, d1, d2 = _cross(ul0, ul1, ul2, ur0, ur1, ur2)
                sn = nb0 * d0 + nb1 * d1 + nb2 * d2
                c = math.asin(sn) / L[h, a] - chi0[h, a]
                dchids = 1.0 / (L[h, a] * math.sqrt(1.0 - sn * sn))
                bl0, bl1, bl2 = _cross(ur0, ur1, ur2, nb0, nb1, nb2)
                br0, br1, br2 = _cross(nb0, nb1, nb2, ul0, ul1, ul2)
            mom, w, dm = bending_law(c, laws[i + 2 * mode[h]])
            chi[h, a] = c
            moment[h, a] = mom
            e_h += w * V[h, a] * inv_T
            # ds/dnl = ds/dnr = q = (I - nbar nbar) ds/dnbar / |m|, ds/dnbar = d
            q0, q1, q2 = _perp(nb0, nb1, nb2, d0, d1, d2, 1.0 / mn)
            scale = inv_T * V[h, a] * mom * dchids  # dW/ds
            _side_adjoint(t, nrm, cn, l, a, i, q0, q1, q2, 1.0 / tl, bl0, bl1, bl2, adj, dchi, h, 0, scale, dchids)
            _side_adjoint(t, nrm, cn, r, a, i, q0, q1, q2, 1.0 / tr, br0, br1, br2, adj, dchi, h, 1, scale, dchids)
            s_abs = 0.0
            for j in range(2):
                s_abs += dchi[h, a, 0, j] * Gsum[l, a, j] + dchi[h, a, 1, j] * Gsum[r, a, j]
            kS[h, a] = inv_T * V[h, a] * (dm + abs(mom) * L[h, a]) * s_abs
        energy[h] = e_h


@njit_parallel
def element_forces(G, el_hinge, adj, fe):
    """fe (n_el, 8, 3) = sum over the element's hinges of dW/dt . dt/dx_n [N]; el_hinge (n_el, 4, 2) holds, per
    family + 2 mode, the hinge to the - neighbour (column 0, where the element is the hinge's right side) and to
    the + neighbour (column 1, left side), -1 if none. Fixed summation order: deterministic on any thread count."""
    for e in prange(G.shape[0]):
        for n in range(8):
            for c in range(3):
                fe[e, n, c] = 0.0
        for a in range(2):
            for j in range(2):
                s0 = 0.0
                s1 = 0.0
                s2 = 0.0
                for k in range(el_hinge.shape[1]):
                    for col in range(2):
                        h = el_hinge[e, k, col]
                        if h >= 0:
                            side = 1 - col
                            s0 += adj[h, a, side, j, 0]
                            s1 += adj[h, a, side, j, 1]
                            s2 += adj[h, a, side, j, 2]
                for n in range(8):
                    g = G[e, a, j, n]
                    fe[e, n, 0] += s0 * g
                    fe[e, n, 1] += s1 * g
                    fe[e, n, 2] += s2 * g


@njit_parallel
def element_rows(G, el_hinge, dchi, kS, rows):
    """Gershgorin row pieces rows (n_el, 8) = sum_h k_h |g_h,n (this element's part)| sum_m |g_h,m| [N/mm]."""
    for e in prange(G.shape[0]):
        for n in range(8):
            acc = 0.0
            for a in range(2):
                for k in range(el_hinge.shape[1]):
                    for col in range(2):
                        h = el_hinge[e, k, col]
                        if h >= 0:
                            side = 1 - col
                            g = dchi[h, a, side, 0] * abs(G[e, a, 0, n]) + dchi[h, a, side, 1] * abs(G[e, a, 1, n])
                            acc += kS[h, a] * g
            rows[e, n] = acc


@njit_parallel
def gather_rows(rows, ptr, slots, out):
    """out (n_node,) = sum of rows (n_el, 8) over each node's slots, in a fixed order."""
    for n in prange(out.shape[0]):
        s = 0.0
        for k in range(ptr[n], ptr[n + 1]):
            s += rows[slots[k] // 8, slots[k] % 8]
        out[n] = s


@njit_parallel
def element_steps(conn, R, mass, dt_group, dt_e, wb_e):
    """dt_e (n_el,) = 2 / sqrt(omega_b^2 + (2 / dt_group)^2), omega_b^2 = max over the element's nodes of R / m,
    itself kept in wb_e (n_el,) [1/s^2]."""
    for e in prange(conn.shape[0]):
        wb = 0.0
        for n in range(8):
            node = conn[e, n]
            wb = max(wb, R[node] / mass[node])
        wg = 2.0 / dt_group[e]
        wb_e[e] = wb
        dt_e[e] = 2.0 / math.sqrt(wb + wg * wg)


# ------------------------------------------------------------------------------------------------------------------
# Effect
# ------------------------------------------------------------------------------------------------------------------

class FibreBendingEffect(Effect):
    """Bending energy of the fibres of one element group; see the module docstring for the formulation."""

    forces = "internal"
    subcycling_safe = True  # its hinges' steps enter the levels (element_dt)
    terms = (Term("bending_energy", STORED),)

    def __init__(self, name, group, X, geo, left, right, fam, laws, thickness, mode=None):
        self.name, self.group = name, group
        self.conn = group.conn
        self.G = geo["G"]
        self.Gsum = np.ascontiguousarray(np.abs(self.G).sum(axis=3))
        self.left, self.right, self.fam = left, right, fam
        self.mode = np.zeros(len(left), np.int64) if mode is None else mode  # 0 out of plane, 1 in plane
        P, Vlev = geo["P"], geo["V"]
        self.L = np.linalg.norm(P[right] - P[left], axis=2)  # (n_h, 2)
        self.V = 0.5 * (Vlev[left] + Vlev[right])
        self.laws, self.inv_T = laws, 1.0 / thickness
        n_el, n_h = len(self.conn), len(left)
        self.el_hinge = np.full((n_el, 4 if self.mode.any() else 2, 2), -1, np.int64)
        self.el_hinge[right, fam + 2 * self.mode, 0] = np.arange(n_h)
        self.el_hinge[left, fam + 2 * self.mode, 1] = np.arange(n_h)
        self.t, self.nrm, self.cn = np.zeros((n_el, 2, 2, 3)), np.zeros((n_el, 2, 3)), np.zeros((n_el, 2))
        self.chi, self.moment, self.e_h = np.zeros((n_h, 2)), np.zeros((n_h, 2)), np.zeros(n_h)
        self.adj, self.dchi, self.kS = np.zeros((n_h, 2, 2, 2, 3)), np.zeros((n_h, 2, 2, 2)), np.zeros((n_h, 2))
        self.fe, self.rows = np.zeros((n_el, 8, 3)), np.zeros((n_el, 8))
        self.R, self.dt_e, self.wb_e = np.zeros(len(X)), np.zeros(n_el), np.zeros(n_el)
        self.ptr, self.slots = node_slots(self.conn, len(X))
        self.chi0 = np.zeros((n_h, 2))
        self._evaluate(X)
        self.chi0 = self.chi.copy()  # the reference configuration is unbent by definition
        self._evaluate(X)  # the rest state (chi = 0): its hinge stiffnesses give the rest step
        self.dchi_rest, self.kS_rest = self.dchi.copy(), self.kS.copy()
        self._energy = 0.0
        self._mass, self._mass_rho = None, None
        self.group_index = None  # index of ``group`` in the problem's groups (set by ``build``; None for a view)
        self._beta = None  # (n_el,) selective mass factors of the current step, or None
        self._trans = None  # (n_el,) translational density of the current step under selective mass, or None

    def coupled_elements(self) -> tuple[np.ndarray, np.ndarray]:
        """(left, right) (n_h,) element indices of each hinge: a hinge's forces depend on the nodes of its two
        elements only (each element's tangents come from its own nodes), which is the coupling a static solver's
        tangent pattern needs (``fdeck.engine.static``)."""
        return self.left, self.right

    def _evaluate(self, x):
        tangents(x, self.conn, self.G, self.t, self.nrm, self.cn)
        hinges(self.t, self.nrm, self.cn, self.left, self.right, self.fam, self.mode, self.L, self.V, self.chi0,
               self.laws,
               self.inv_T, self.Gsum, self.chi, self.moment, self.e_h, self.adj, self.dchi, self.kS)

    def add_force(self, t, x, v, f):
        self._evaluate(x)
        element_forces(self.G, self.el_hinge, self.adj, self.fe)
        gather_add(self.fe, self.ptr, self.slots, f)
        self._energy = float(np.sum(self.e_h))

    def term_values(self) -> tuple[float]:
        """Stored bending energy [mJ] at the last ``add_force``."""
        return (self._energy,)

    def begin_step(self, index: int, plan) -> None:
        """Under selective mass scaling the hinges see the translational mass only: the added mass sits on each
        element's deformation modes, and the hinges turn whole elements (``own_omega2``)."""
        if plan.selective is not None and self.group_index is None:
            raise RuntimeError("selective mass scaling with fibre bending on subcycling blocks")  # refused earlier
        self._beta = None if plan.selective is None else plan.selective[self.group_index]
        # the translational density of the step: fixed while selective mass is tracked (``track_target`` raises
        # the group's density on the deformation modes only, in place)
        self._trans = None if plan.selective is None else plan.rho[self.group_index] / (1.0 + self._beta)
        self._mass_rho = None

    def nodal_mass(self) -> np.ndarray:
        """(n_node,) lumped mass of this group's elements [t] with the group's current density (mass scaling
        included; under selective scaling its translational part, rho / (1 + beta)); nodes shared with other groups
        get only this group's share, which errs on the safe side."""
        rho = self.group.rho if self._trans is None else self._trans
        if self._mass_rho is not rho:
            self._mass, self._mass_rho = self._lump(self.group.mass(rho)), rho
        return self._mass

    def _lump(self, m_el: np.ndarray) -> np.ndarray:
        """(n_node,) sum of element nodal masses m_el (n_el, 8) [t]; inf where this group has no mass (so that
        R / m vanishes off the group)."""
        m = np.zeros(len(self.R))
        np.add.at(m, self.conn.ravel(), m_el.ravel())
        return np.where(m > 0, m, np.inf)

    def stable_dt(self) -> float:
        """Smallest element step [s] of bending and continuum together, from the state of the last add_force."""
        element_rows(self.G, self.el_hinge, self.dchi, self.kS, self.rows)
        gather_rows(self.rows, self.ptr, self.slots, self.R)
        self.group.stable_dt()  # refreshes group.dt_e from the current moduli (independent of call order)
        element_steps(self.conn, self.R, self.nodal_mass(), self.group.dt_e, self.dt_e, self.wb_e)
        return float(self.dt_e.min())

    def element_dt(self) -> np.ndarray:
        """(n_el,) element steps [s], bending and continuum together, from the last ``stable_dt``."""
        return self.dt_e

    def rotation_omega2(self) -> np.ndarray:
        """(n_el,) the hinges' own squared frequency omega_b^2 [1/s^2] per element (the largest R / m of its nodes)
        at the last ``stable_dt``: what selective mass tracking cannot slow (``selective_mass``)."""
        return self.wb_e

    def rest_dt(self, rho: np.ndarray) -> np.ndarray:
        """(n_el,) element steps [s] at rest, bending and continuum together, with the group's densities rho
        (n_el,) [t/mm^3]: what mass scaling to a target step and ``fdeck info`` need before the run."""
        return 2.0 / np.sqrt(self.own_omega2(rho) + (2.0 / self.group.rest_dt(rho)) ** 2)

    def own_omega2(self, rho: np.ndarray) -> np.ndarray:
        """(n_el,) the hinges' own squared frequency bound omega_b^2 [1/s^2] per element at rest (the largest R / m
        of its nodes, module docstring) against the lumped mass of densities rho (n_el,) [t/mm^3]. The hinges turn
        whole elements, on which selective mass adds nothing: with it, rho is the translational density and the
        element step 2 / sqrt(omega_g^2 / (1 + beta) + omega_b^2) (``compile.problem.selective_density``)."""
        m = self._lump(self.group.mass(rho))
        rows, R = np.zeros_like(self.rows), np.zeros_like(self.R)
        element_rows(self.G, self.el_hinge, self.dchi_rest, self.kS_rest, rows)
        gather_rows(rows, self.ptr, self.slots, R)
        return (R / m)[self.conn].max(axis=1)

    def curvatures(self) -> dict[str, np.ndarray]:
        """Current hinge curvatures [1/mm] per family and mode: 'warp', 'weft' (out of plane), 'warp_in_plane',
        'weft_in_plane' -> (n_hinge, 2 levels); only those the effect has."""
        out = {}
        for m, suffix in ((0, ""), (1, "_in_plane")):
            for i in range(2):
                sel = (self.fam == i) & (self.mode == m)
                if sel.any():
                    out[FAMILIES[i] + suffix] = self.chi[sel]
        return out


def build(card: FibreBending, ctx) -> FibreBendingEffect:
    """Registry hook: one effect per element group of the section (``ctx.group``)."""
    g = ctx.group
    laws = np.zeros((4, LAW_SIZE))
    left, right, fam, mode = [], [], [], []
    inp = card.in_plane
    wanted = [(i, 0, law) for i, law in enumerate((card.warp, card.weft))]
    wanted += [(i, 1, law) for i, law in enumerate((inp.warp, inp.weft) if inp is not None else (None, None))]
    try:
        geo = level_geometry(ctx.X, g.conn, g.frame)
        neighbours = {}
        for i, m, law in wanted:
            if law is None:
                continue
            laws[i + 2 * m] = pack_law(law)
            if i not in neighbours:
                neighbours[i] = fibre_neighbours(ctx.X, g.conn, g.frame, i)
            nb = neighbours[i]
            e = np.nonzero(nb[:, 1] >= 0)[0]
            left.append(e)
            right.append(nb[e, 1])
            fam.append(np.full(len(e), i, np.int64))
            mode.append(np.full(len(e), m, np.int64))
    except MeshNotAligned as exc:
        ids = g.ids[exc.local]
        listed = ", ".join(map(str, ids[:10])) + (", ..." if len(ids) > 10 else "")
        raise CompileError([(ctx.path, f"{len(ids)} elements of {g.name} {exc.what} (ids {listed})")]) from None
    left, right, fam, mode = (np.concatenate(a).astype(np.int64) for a in (left, right, fam, mode))
    if len(left) == 0:
        raise CompileError([(ctx.path, f"no two elements of {g.name} are neighbours along a bending family: "
                             "fibre bending needs at least two elements along warp or weft")])
    effect = FibreBendingEffect(f"fibre_bending:{g.name}", g, ctx.X, geo, left, right, fam, laws, card.thickness,
                                mode)
    effect.group_index = next((i for i, h in enumerate(getattr(ctx, "groups", ())) if h is g), None)
    return effect


register_effect(EffectKind("fibre_bending", build))
