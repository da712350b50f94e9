"""Four-node shells for thin fabrics (triangles as degenerate quadrilaterals): sections `sm`, `ts` and `membrane`.

Kinematics (total Lagrangian, degenerated solid with a director, Simo & Fox 1989 in spirit). Bilinear mid-surface
x(xi, eta) = sum_a N_a x_a and director field d(xi, eta) = sum_a N_a d_a from the nodal unit directors; a point at
the physical height z (-h/2 <= z <= h/2) on the thickness line is x + z d. At every in-plane Gauss point (2 x 2) and
through-thickness level z the reference covariant vectors G_1 = X,xi + z D,xi, G_2 = X,eta + z D,eta, G_3 = D have
the dual basis G^i, and the deformation gradient maps them to g_1, g_2, g_3 = x,xi + z d,xi, ... . With the local
reference basis e_1 = warp, e_2 = weft (in the mid-surface tangent plane, e_3 = its normal N) the law gets

    F = A_1 (x) e_1 + A_2 (x) e_2 + n (x) N,   A_k = F e_k = sum_j T_kj g_j + tau_k d,   T_kj = e_k . G^j,
    tau_k = e_k . G^3, n = unit normal to A_1, A_2,

exactly I at rest for flat or curved references, and a function of current inner products only: rigid motions of
(x, d) give no strain, so the element is objective under arbitrarily large rotations without a co-rotational frame.
Plane stress (the law's S N = 0, ``MaterialKind.plane_stress``): the work is w P : dF = w sum_k (P e_k) . dA_k.

Sections
* ``membrane``: one level z = 0 of weight h; no director, no bending (fabric in-plane law only).
* ``sm`` (shell-membrane hybrid of [J]): the membrane above plus a decoupled orthotropic elastic bending energy
  1/2 (D11 k11^2 + D22 k22^2 + 4 D66 k12^2) per reference area with D11 = D22 = EI (per unit width, along the yarns)
  and D66 = GI, on the bending strain k_kl = (A_k . B_l + A_l . B_k)/2 - k0_kl, B_l = sum_j T_lj d,j (the z-linear
  part of the Green-Lagrange strain; k0 its reference value). The 45-deg strip of this plate bends with
  EI_45 = 1 / (1/(2 EI) + 1/(4 GI)) (no bending-twisting coupling at 45 deg since D11 = D22), which gives GI from a
  45-deg bending test. Kirchhoff-Love in effect: a transverse shear penalty k_s = min(alpha 12 D_max / A_e,
  beta_s M0 h) [N/mm] (A_e the element area, M0 the law's rest wave modulus, alpha = `transverse_shear_penalty`,
  beta_s = 1/4) makes the shear share of a three-point bending deflection 12 EI / (k_s l^2) = A_e / (alpha l^2) for
  fabrics (1e-5 for 1 mm elements on a 30 mm span), while the second bound keeps the shear wave below a quarter of
  the membrane one so it never sets the step.
* ``ts`` (thick shell of [J], Reissner-Mindlin): N levels through the thickness (Gauss or Gauss-Lobatto), each
  carrying the fabric law, so bending comes from fibre tension and compression across the section; transverse
  shear energy 1/2 k_s |gamma|^2 per area with k_s = kappa G13 h (G13 = G23, kappa = `shear_correction`, 5/6 by
  default: the Timoshenko/Mindlin factor of a homogeneous rectangular section, alpha = 1/kappa = 6/5 in MODELS 5).

Transverse shear against locking: MITC4 (Bathe & Dvorkin, Int J Num Meth Eng 21 (1985) 367): the covariant shear
strains x,xi . d - X,xi . D are sampled at the four edge midpoints and interpolated linearly across the element.
Passes the constant-curvature patch test with zero shear, represents constant shear exactly (degenerate
triangles included: the collapsed edge's covariant strain is identically zero) and removes shear locking (the
thin-strip tests in tests/test_shell_verification.py). 2 x 2 integration of every term: no zero-energy modes to
control, at about 4x the cost of one-point Belytschko-Tsay, which needs hourglass control (a source of
mesh-dependent stiffness in soft fabrics) and is not objective under large in-plane shear without extra work.

Director-normal tie (section key ``normal_stiffness`` k_n [N/mm], off by default): the MITC4 shear sees only the
mean of an edge's two end directors, so along an element-scale zig-zag of the mid-surface consecutive directors may
turn by the zig-zag's slope each, without bound and without shear energy (the spiral the square-tube flanges showed,
directors 112-116 deg off the normal, det F <= 0); a dry fabric's bending stiffness and G13 are too small to stop it.
The tie adds W_n = sum_a k_n A_a (1 - d_a . n_a) (about 1/2 k_n A_a theta_a^2: a transverse shear of the director
against the surface normal, the same units as k_s) with n_a the unit nodal normal of the mid-surface (sum of the
section's element vector areas (x_3 - x_1) x (x_4 - x_2) / 2 at the node), A_a the node's tributary area; its nodal
forces by the chain rule through the vector areas, its moments -k_n A_a d_a x n_a, its energy the ledger part
``director_normal_energy``. Exact derivatives and objectivity: tests/test_shell_director_tie.py.

Masses: lumped row sums, m_a = rho h integral N_a dA (triangles: A/3 per node). Rotational inertia, lumped per node
and scalar: I_a = m_a r_e^2 with r_e^2 = max(h^2/12, r_needed^2): h^2/12 is the physical rotary inertia of the
section; r_needed (per element, from the rest state) makes every rotational stiffness of the element (sm bending,
shear through the director, and for ts the levels' coupling z^2 through the membrane moduli) at most beta = 1/4 of
the element's membrane eigenvalue bound, so rotations never set the step (standard practice; the added inertia
is reported as ``added_rotational_inertia``). Only quasi-static answers are meant: rotations are slowed, not
translations.

Stable step: dt_e = 2 sqrt(rho / (4 s + C)) with s the hexahedron rule in 2-D (``hex8.element_dt``: the fibre wave
moduli of the law, each over the element's length along its fibre), the moduli taken as the thickness average of
m_l (1 + z_l^2 / r_e^2) (the director's share of a membrane mode through the levels), and C the Frobenius bounds of
the bending and transverse-shear stiffness over the lumped masses and inertias, from the rest state (linear
parts). Checked against the exact critical step of assembled meshes (FD stiffness of forces and director forces,
lumped masses and inertias) in tests/test_shell_step.py.

Arrays: conn (n_el, 4) with node 3 = node 2 for triangles; per element, Gauss point g (4) and level l: T (2, 2),
tau (2), w (volume weight [mm^3]); per (element, g): e_1, e_2, N, mid-surface T0, tau0, aw (area weight [mm^2]),
k0 (3). Units: mm, N, MPa, t.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.gather import gather_add
from fdeck.engine.ledger import PART, STORED, Term
from fdeck.physics.elements import diagnostics
from fdeck.jit import njit, njit_parallel, prange
from fdeck.registry import FormulationKind, register_formulation

SIGNS = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_G = 1.0 / math.sqrt(3.0)
GAUSS = SIGNS * _G  # 2 x 2 points, unit weights, in node order
N_GP = np.array([0.25 * (1 + SIGNS[:, 0] * xi) * (1 + SIGNS[:, 1] * eta) for xi, eta in GAUSS])  # (4 gp, 4 nodes)
DN_GP = np.array([np.stack([0.25 * SIGNS[:, 0] * (1 + SIGNS[:, 1] * eta), 0.25 * SIGNS[:, 1] * (1 + SIGNS[:, 0] * xi)],
                           axis=1) for xi, eta in GAUSS])  # (4 gp, 4 nodes, 2)
EDGES = np.array([[0, 1], [1, 2], [3, 2], [0, 3]])
"""MITC4 tying edges A (xi, eta = -1), B (eta, xi = +1), C (xi, eta = +1), D (eta, xi = -1) as (p, q): the
covariant strain of an edge is (x_q - x_p)/2 . (d_p + d_q)/2."""

BETA = 0.25
"""Largest share of the element's membrane eigenvalue bound left to rotational stiffness (sets the inertia)."""
BETA_SHEAR = 0.25
"""Largest ratio of the sm shear penalty k_s to the membrane stiffness M0 h (keeps the shear wave off the step)."""



# ----------------------------------------------------------------------------------------------------------------
# Section cards
# ----------------------------------------------------------------------------------------------------------------











def through_thickness(rule: str, n: int, h: float) -> tuple[np.ndarray, np.ndarray]:
    """(heights z (n,) [mm], weights (n,) [mm], summing to h) of an n-point Gauss or Gauss-Lobatto rule."""
    if rule == "gauss":
        s, w = np.polynomial.legendre.leggauss(n)
    else:
        inner = np.polynomial.legendre.Legendre.basis(n - 1).deriv().roots()
        s = np.concatenate([[-1.0], np.sort(inner.real), [1.0]])
        pn = np.polynomial.legendre.Legendre.basis(n - 1)(s)
        w = 2.0 / (n * (n - 1) * pn**2)
    return 0.5 * h * s, 0.5 * h * w


# ----------------------------------------------------------------------------------------------------------------
# Reference geometry (numpy, once)
# ----------------------------------------------------------------------------------------------------------------

def local_bases(Xe: np.ndarray, orientation) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """-> (e1, e2, N (n_el, 4, 3) at the Gauss points, bad (n_el,) bool).

    orientation: ``fdeck.compile.orientation.ElementOrientation`` (reference (n_el, 3), warp_angle (n_el,) [deg],
    normal (3,)). N is the unit mid-surface normal from the node order; e1 (warp) is the element's reference
    direction projected on the tangent plane and turned by its warp angle about N taken on the side of the
    orientation normal; e2 (weft) = (that normal) x e1. ``bad``: reference direction (nearly) normal to the element.
    """
    Xxi = np.einsum("gaj,eai->egji", DN_GP, Xe)  # (n_el, 4, 2, 3): X,xi and X,eta
    n = np.cross(Xxi[:, :, 0], Xxi[:, :, 1])
    N = n / np.linalg.norm(n, axis=-1, keepdims=True)
    r = np.asarray(orientation.reference, float)[:, None, :]  # (n_el, 1, 3)
    rp = r - np.sum(N * r, axis=-1, keepdims=True) * N
    norm = np.linalg.norm(rp, axis=-1)
    bad = (norm < 1e-6 * np.linalg.norm(r, axis=-1)).any(axis=1)
    rp = rp / np.where(norm > 0, norm, 1.0)[..., None]
    side = np.sign(np.einsum("egi,i->eg", N, np.asarray(orientation.normal, float)))
    side = np.where(side == 0, 1.0, side)[..., None]
    a = np.radians(np.asarray(orientation.warp_angle, float))[:, None, None]  # (n_el, 1, 1)
    sN = side * N
    e1 = np.cos(a) * rp + np.sin(a) * np.cross(sN, rp)
    e2 = np.cross(sN, e1)
    return e1, e2, N, bad


def level_maps(Xe, De, e1, e2, z, G3=None):
    """T (n_el, 4, n_z, 2, 2), tau (n_el, 4, n_z, 2), det (n_el, 4, n_z) of [G_1 G_2 G_3] at heights z, with the
    reference directors De (n_el, 4, 3) at the nodes, or (membranes, G3 given) the unit normal G3 (n_el, 4, 3) at
    each Gauss point as G_3 and no director derivative."""
    Xxi = np.einsum("gaj,eai->egji", DN_GP, Xe)
    if G3 is None:
        Dxi = np.einsum("gaj,eai->egji", DN_GP, De)
        Dbar = np.einsum("ga,eai->egi", N_GP, De)
    else:
        Dxi, Dbar = np.zeros_like(Xxi), G3
    G = np.empty(Xxi.shape[:2] + (len(z), 3, 3))
    for l, zl in enumerate(z):
        G[:, :, l, :, 0] = Xxi[:, :, 0] + zl * Dxi[:, :, 0]
        G[:, :, l, :, 1] = Xxi[:, :, 1] + zl * Dxi[:, :, 1]
        G[:, :, l, :, 2] = Dbar
    det = np.linalg.det(G)
    Ginv = np.linalg.inv(G)  # rows: dual vectors G^j
    ek = np.stack([e1, e2], axis=2)  # (n_el, 4, 2, 3)
    TT = np.einsum("eglji,egki->eglkj", Ginv, ek)  # (n_el, 4, n_z, 2, 3): e_k . G^j for j = 1, 2, 3
    return np.ascontiguousarray(TT[..., :2]), np.ascontiguousarray(TT[..., 2]), det


def edge_strains(x, d, conn):
    """Covariant MITC tying strains (n_el, 4) at edges A, B, C, D: (x_q - x_p)/2 . (d_p + d_q)/2."""
    p, q = conn[:, EDGES[:, 0]], conn[:, EDGES[:, 1]]
    return 0.25 * np.einsum("eki,eki->ek", x[q] - x[p], d[p] + d[q])


# ----------------------------------------------------------------------------------------------------------------
# Kernels
# ----------------------------------------------------------------------------------------------------------------

@njit_parallel
def kinematics(x, d, conn, T, tau, z, e1, e2, nrm, T0, tau0, has_dir, F, J):
    """F (n_el, 4, n_z, 3, 3) at every Gauss point and level; J (n_el, 4) mid-surface area ratio, signed by the
    director (negative: the element folded over its directors). x, d (n_node, 3); d unused without directors."""
    n_z = z.shape[0]
    for e in prange(conn.shape[0]):
        for g in range(4):
            xa0 = 0.0
            xa1 = 0.0
            xa2 = 0.0
            xb0 = 0.0
            xb1 = 0.0
            xb2 = 0.0
            da0 = 0.0
            da1 = 0.0
            da2 = 0.0
            db0 = 0.0
            db1 = 0.0
            db2 = 0.0
            dm0 = 0.0
            dm1 = 0.0
            dm2 = 0.0
            for a in range(4):
                n = conn[e, a]
                sa, sb = _dn(g, a)
                xa0 += sa * x[n, 0]
                xa1 += sa * x[n, 1]
                xa2 += sa * x[n, 2]
                xb0 += sb * x[n, 0]
                xb1 += sb * x[n, 1]
                xb2 += sb * x[n, 2]
                if has_dir:
                    na = _n(g, a)
                    da0 += sa * d[n, 0]
                    da1 += sa * d[n, 1]
                    da2 += sa * d[n, 2]
                    db0 += sb * d[n, 0]
                    db1 += sb * d[n, 1]
                    db2 += sb * d[n, 2]
                    dm0 += na * d[n, 0]
                    dm1 += na * d[n, 1]
                    dm2 += na * d[n, 2]
            # mid-surface area ratio
            t = T0[e, g]
            u = tau0[e, g]
            p0 = t[0, 0] * xa0 + t[0, 1] * xb0 + u[0] * dm0
            p1 = t[0, 0] * xa1 + t[0, 1] * xb1 + u[0] * dm1
            p2 = t[0, 0] * xa2 + t[0, 1] * xb2 + u[0] * dm2
            q0 = t[1, 0] * xa0 + t[1, 1] * xb0 + u[1] * dm0
            q1 = t[1, 0] * xa1 + t[1, 1] * xb1 + u[1] * dm1
            q2 = t[1, 0] * xa2 + t[1, 1] * xb2 + u[1] * dm2
            c0, c1, c2 = p1 * q2 - p2 * q1, p2 * q0 - p0 * q2, p0 * q1 - p1 * q0
            area = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
            if has_dir:
                J[e, g] = (c0 * dm0 + c1 * dm1 + c2 * dm2) / math.sqrt(dm0 * dm0 + dm1 * dm1 + dm2 * dm2)
            else:
                J[e, g] = area
            for l in range(n_z):
                zl = z[l]
                g10, g11, g12 = xa0 + zl * da0, xa1 + zl * da1, xa2 + zl * da2
                g20, g21, g22 = xb0 + zl * db0, xb1 + zl * db1, xb2 + zl * db2
                t = T[e, g, l]
                u = tau[e, g, l]
                a10 = t[0, 0] * g10 + t[0, 1] * g20 + u[0] * dm0
                a11 = t[0, 0] * g11 + t[0, 1] * g21 + u[0] * dm1
                a12 = t[0, 0] * g12 + t[0, 1] * g22 + u[0] * dm2
                a20 = t[1, 0] * g10 + t[1, 1] * g20 + u[1] * dm0
                a21 = t[1, 0] * g11 + t[1, 1] * g21 + u[1] * dm1
                a22 = t[1, 0] * g12 + t[1, 1] * g22 + u[1] * dm2
                m0, m1, m2 = a11 * a22 - a12 * a21, a12 * a20 - a10 * a22, a10 * a21 - a11 * a20
                r = 1.0 / math.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
                m0 *= r
                m1 *= r
                m2 *= r
                f = F[e, g, l]
                for i in range(3):
                    f[0, i] = a10 * e1[e, g, i] + a20 * e2[e, g, i] + m0 * nrm[e, g, i]
                    f[1, i] = a11 * e1[e, g, i] + a21 * e2[e, g, i] + m1 * nrm[e, g, i]
                    f[2, i] = a12 * e1[e, g, i] + a22 * e2[e, g, i] + m2 * nrm[e, g, i]


_GQ = 1.0 / math.sqrt(3.0)


@njit_parallel
def forces(x, d, conn, T, tau, z, w, e1, e2, P, psi, T0, tau0, aw, k0, bend, ks, gam0, has_dir, fe, ge, me, energy):
    """Element nodal forces fe (n_el, 4, 3) [N] = dW/dx_a, director forces ge (n_el, 4, 3) [N mm] = dW/dd_a and
    moments me = d_a x ge_a, with W the law's energy sum w psi (P (n_el, 4, n_z, 3, 3), psi (n_el, 4, n_z) from the
    material) plus the sm bending energy (bend (n_el, 3) = D11, D22, D66 [N mm]; k0 (n_el, 4, 3) reference k11,
    k22, k12) and the MITC4 transverse shear energy (ks (n_el,) [N/mm], gam0 (n_el, 4) reference tying strains);
    energy (n_el, 3) [mJ]: the law's, bending, transverse shear."""
    n_z = z.shape[0]
    for e in prange(conn.shape[0]):
        for a in range(4):
            for i in range(3):
                fe[e, a, i] = 0.0
                ge[e, a, i] = 0.0
        em = 0.0
        eb = 0.0
        es = 0.0
        om0 = 0.0  # MITC edge weights: sum over points of aw dW/dgamma_edge
        om1 = 0.0
        om2 = 0.0
        om3 = 0.0
        shear = ks[e] > 0.0
        gA = gB = gC = gD = 0.0
        if shear:
            gA = _edge(x, d, conn, e, 0, 1) - gam0[e, 0]
            gB = _edge(x, d, conn, e, 1, 2) - gam0[e, 1]
            gC = _edge(x, d, conn, e, 3, 2) - gam0[e, 2]
            gD = _edge(x, d, conn, e, 0, 3) - gam0[e, 3]
        bending = bend[e, 0] > 0.0 or bend[e, 1] > 0.0 or bend[e, 2] > 0.0
        for g in range(4):
            xa0 = 0.0
            xa1 = 0.0
            xa2 = 0.0
            xb0 = 0.0
            xb1 = 0.0
            xb2 = 0.0
            da0 = 0.0
            da1 = 0.0
            da2 = 0.0
            db0 = 0.0
            db1 = 0.0
            db2 = 0.0
            dm0 = 0.0
            dm1 = 0.0
            dm2 = 0.0
            if bending:
                for a in range(4):
                    n = conn[e, a]
                    sa, sb = _dn(g, a)
                    na = _n(g, a)
                    xa0 += sa * x[n, 0]
                    xa1 += sa * x[n, 1]
                    xa2 += sa * x[n, 2]
                    xb0 += sb * x[n, 0]
                    xb1 += sb * x[n, 1]
                    xb2 += sb * x[n, 2]
                    da0 += sa * d[n, 0]
                    da1 += sa * d[n, 1]
                    da2 += sa * d[n, 2]
                    db0 += sb * d[n, 0]
                    db1 += sb * d[n, 1]
                    db2 += sb * d[n, 2]
                    dm0 += na * d[n, 0]
                    dm1 += na * d[n, 1]
                    dm2 += na * d[n, 2]
            # membrane / through-thickness levels: dW = w sum_k (P e_k) . dA_k
            for l in range(n_z):
                t = T[e, g, l]
                u = tau[e, g, l]
                wl = w[e, g, l]
                zl = z[l]
                em += wl * psi[e, g, l]
                pf = P[e, g, l]
                q10 = wl * (pf[0, 0] * e1[e, g, 0] + pf[0, 1] * e1[e, g, 1] + pf[0, 2] * e1[e, g, 2])
                q11 = wl * (pf[1, 0] * e1[e, g, 0] + pf[1, 1] * e1[e, g, 1] + pf[1, 2] * e1[e, g, 2])
                q12 = wl * (pf[2, 0] * e1[e, g, 0] + pf[2, 1] * e1[e, g, 1] + pf[2, 2] * e1[e, g, 2])
                q20 = wl * (pf[0, 0] * e2[e, g, 0] + pf[0, 1] * e2[e, g, 1] + pf[0, 2] * e2[e, g, 2])
                q21 = wl * (pf[1, 0] * e2[e, g, 0] + pf[1, 1] * e2[e, g, 1] + pf[1, 2] * e2[e, g, 2])
                q22 = wl * (pf[2, 0] * e2[e, g, 0] + pf[2, 1] * e2[e, g, 1] + pf[2, 2] * e2[e, g, 2])
                for a in range(4):
                    sa, sb = _dn(g, a)
                    c1 = t[0, 0] * sa + t[0, 1] * sb
                    c2 = t[1, 0] * sa + t[1, 1] * sb
                    fe[e, a, 0] += q10 * c1 + q20 * c2
                    fe[e, a, 1] += q11 * c1 + q21 * c2
                    fe[e, a, 2] += q12 * c1 + q22 * c2
                    if has_dir:
                        na = _n(g, a)
                        h1 = zl * c1 + u[0] * na
                        h2 = zl * c2 + u[1] * na
                        ge[e, a, 0] += q10 * h1 + q20 * h2
                        ge[e, a, 1] += q11 * h1 + q21 * h2
                        ge[e, a, 2] += q12 * h1 + q22 * h2
            t = T0[e, g]
            u = tau0[e, g]
            ag = aw[e, g]
            if bending:
                A10 = t[0, 0] * xa0 + t[0, 1] * xb0 + u[0] * dm0
                A11 = t[0, 0] * xa1 + t[0, 1] * xb1 + u[0] * dm1
                A12 = t[0, 0] * xa2 + t[0, 1] * xb2 + u[0] * dm2
                A20 = t[1, 0] * xa0 + t[1, 1] * xb0 + u[1] * dm0
                A21 = t[1, 0] * xa1 + t[1, 1] * xb1 + u[1] * dm1
                A22 = t[1, 0] * xa2 + t[1, 1] * xb2 + u[1] * dm2
                B10 = t[0, 0] * da0 + t[0, 1] * db0
                B11 = t[0, 0] * da1 + t[0, 1] * db1
                B12 = t[0, 0] * da2 + t[0, 1] * db2
                B20 = t[1, 0] * da0 + t[1, 1] * db0
                B21 = t[1, 0] * da1 + t[1, 1] * db1
                B22 = t[1, 0] * da2 + t[1, 1] * db2
                k11 = A10 * B10 + A11 * B11 + A12 * B12 - k0[e, g, 0]
                k22 = A20 * B20 + A21 * B21 + A22 * B22 - k0[e, g, 1]
                k12 = 0.5 * (A10 * B20 + A11 * B21 + A12 * B22 + A20 * B10 + A21 * B11 + A22 * B12) - k0[e, g, 2]
                D11, D22, D66 = bend[e, 0], bend[e, 1], bend[e, 2]
                eb += 0.5 * ag * (D11 * k11 * k11 + D22 * k22 * k22 + 4.0 * D66 * k12 * k12)
                m11, m22, m12 = ag * D11 * k11, ag * D22 * k22, ag * 2.0 * D66 * k12
                # dW = dA_1 . p1 + dA_2 . p2 + dB_1 . r1 + dB_2 . r2
                p10, p11, p12 = m11 * B10 + m12 * B20, m11 * B11 + m12 * B21, m11 * B12 + m12 * B22
                p20, p21, p22 = m22 * B20 + m12 * B10, m22 * B21 + m12 * B11, m22 * B22 + m12 * B12
                r10, r11, r12 = m11 * A10 + m12 * A20, m11 * A11 + m12 * A21, m11 * A12 + m12 * A22
                r20, r21, r22 = m22 * A20 + m12 * A10, m22 * A21 + m12 * A11, m22 * A22 + m12 * A12
                for a in range(4):
                    sa, sb = _dn(g, a)
                    na = _n(g, a)
                    c1 = t[0, 0] * sa + t[0, 1] * sb
                    c2 = t[1, 0] * sa + t[1, 1] * sb
                    fe[e, a, 0] += p10 * c1 + p20 * c2
                    fe[e, a, 1] += p11 * c1 + p21 * c2
                    fe[e, a, 2] += p12 * c1 + p22 * c2
                    h1, h2 = u[0] * na, u[1] * na
                    ge[e, a, 0] += p10 * h1 + p20 * h2 + r10 * c1 + r20 * c2
                    ge[e, a, 1] += p11 * h1 + p21 * h2 + r11 * c1 + r21 * c2
                    ge[e, a, 2] += p12 * h1 + p22 * h2 + r12 * c1 + r22 * c2
            if shear:
                xi, eta = _xi(g), _eta(g)
                gx = 0.5 * (1.0 - eta) * gA + 0.5 * (1.0 + eta) * gC
                gy = 0.5 * (1.0 - xi) * gD + 0.5 * (1.0 + xi) * gB
                s1 = t[0, 0] * gx + t[0, 1] * gy
                s2 = t[1, 0] * gx + t[1, 1] * gy
                es += 0.5 * ag * ks[e] * (s1 * s1 + s2 * s2)
                Qx = ag * ks[e] * (s1 * t[0, 0] + s2 * t[1, 0])
                Qy = ag * ks[e] * (s1 * t[0, 1] + s2 * t[1, 1])
                om0 += 0.5 * (1.0 - eta) * Qx
                om2 += 0.5 * (1.0 + eta) * Qx
                om3 += 0.5 * (1.0 - xi) * Qy
                om1 += 0.5 * (1.0 + xi) * Qy
        if shear:
            _edge_force(x, d, conn, e, 0, 1, om0, fe, ge)
            _edge_force(x, d, conn, e, 1, 2, om1, fe, ge)
            _edge_force(x, d, conn, e, 3, 2, om2, fe, ge)
            _edge_force(x, d, conn, e, 0, 3, om3, fe, ge)
        energy[e, 0] = em
        energy[e, 1] = eb
        energy[e, 2] = es
        if has_dir:
            for a in range(4):
                n = conn[e, a]
                me[e, a, 0] = d[n, 1] * ge[e, a, 2] - d[n, 2] * ge[e, a, 1]
                me[e, a, 1] = d[n, 2] * ge[e, a, 0] - d[n, 0] * ge[e, a, 2]
                me[e, a, 2] = d[n, 0] * ge[e, a, 1] - d[n, 1] * ge[e, a, 0]


@njit
def _dn(g, a):
    """dN_a/dxi, dN_a/deta at Gauss point g (points and nodes in the order of SIGNS)."""
    sx = -1.0 if a == 0 or a == 3 else 1.0
    sy = -1.0 if a < 2 else 1.0
    xi = _xi(g)
    eta = _eta(g)
    return 0.25 * sx * (1.0 + sy * eta), 0.25 * sy * (1.0 + sx * xi)


@njit
def _n(g, a):
    sx = -1.0 if a == 0 or a == 3 else 1.0
    sy = -1.0 if a < 2 else 1.0
    return 0.25 * (1.0 + sx * _xi(g)) * (1.0 + sy * _eta(g))


@njit
def _xi(g):
    return -_GQ if g == 0 or g == 3 else _GQ


@njit
def _eta(g):
    return -_GQ if g < 2 else _GQ


@njit
def _edge(x, d, conn, e, a, b):
    p, q = conn[e, a], conn[e, b]
    return 0.25 * ((x[q, 0] - x[p, 0]) * (d[p, 0] + d[q, 0]) + (x[q, 1] - x[p, 1]) * (d[p, 1] + d[q, 1])
                   + (x[q, 2] - x[p, 2]) * (d[p, 2] + d[q, 2]))


@njit
def _edge_force(x, d, conn, e, a, b, om, fe, ge):
    """Add om d(gamma_edge) for the tying strain (x_b - x_a)/2 . (d_a + d_b)/2 of slots a, b."""
    p, q = conn[e, a], conn[e, b]
    for i in range(3):
        fd = 0.25 * om * (d[p, i] + d[q, i])
        gd = 0.25 * om * (x[q, i] - x[p, i])
        fe[e, b, i] += fd
        fe[e, a, i] -= fd
        ge[e, a, i] += gd
        ge[e, b, i] += gd


@njit_parallel
def element_dt(modulus, wz, fz, L0, inv_len2, C, rho, dt_e):
    """dt_e (n_el,) [s] = 2 sqrt(rho / (4 s + C)).

    modulus (n_el, 4, n_z, 3) the law's bounds along warp, weft, normal; wz (n_z,) level weights over h; fz (n_el,
    n_z) = 1 + z^2 / r_e^2 (the director's share through the levels); M_k = max over points of sum_z wz fz m_k;
    s = M_min / L0^2 + max_k (M_k - M_min) / L_k^2 (inv_len2 (n_el, 2) = 1 / L_k^2); C (n_el,) [MPa/mm^2 ...] the
    bending and shear bound times rho; rho (n_el,) [t/mm^3].
    """
    for e in prange(L0.shape[0]):
        M1 = 0.0
        M2 = 0.0
        M3 = 0.0
        for g in range(4):
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            for l in range(wz.shape[0]):
                s1 += wz[l] * fz[e, l] * modulus[e, g, l, 0]
                s2 += wz[l] * fz[e, l] * modulus[e, g, l, 1]
                s3 += wz[l] * fz[e, l] * modulus[e, g, l, 2]
            M1 = max(M1, s1)
            M2 = max(M2, s2)
            M3 = max(M3, s3)
        lo = min(M1, M2, M3)
        s = lo / (L0[e] * L0[e]) + max((M1 - lo) * inv_len2[e, 0], (M2 - lo) * inv_len2[e, 1])
        den = 4.0 * s + C[e]
        dt_e[e] = 2.0 * math.sqrt(rho[e] / den) if den > 0.0 else np.inf


@njit_parallel
def tie_areas(x, conn, mask, out):
    """out (n_el, 4, 3) = mask_a S_e: the element's vector area (x_3 - x_1) x (x_4 - x_2) / 2 at each slot [mm^2]."""
    for e in prange(conn.shape[0]):
        i0, i1, i2, i3 = conn[e, 0], conn[e, 1], conn[e, 2], conn[e, 3]
        A0, A1, A2 = x[i2, 0] - x[i0, 0], x[i2, 1] - x[i0, 1], x[i2, 2] - x[i0, 2]
        B0, B1, B2 = x[i3, 0] - x[i1, 0], x[i3, 1] - x[i1, 1], x[i3, 2] - x[i1, 2]
        S0, S1, S2 = 0.5 * (A1 * B2 - A2 * B1), 0.5 * (A2 * B0 - A0 * B2), 0.5 * (A0 * B1 - A1 * B0)
        for a in range(4):
            out[e, a, 0] = mask[e, a] * S0
            out[e, a, 1] = mask[e, a] * S1
            out[e, a, 2] = mask[e, a] * S2


@njit_parallel
def tie_nodes(d, Sn, kappa, tied, v, m, e_node):
    """Per tied node a: e_node = kappa (1 - d . n), v = dW/dS_a = -kappa (d - (d . n) n) / |S_a|, m = -kappa d x n
    (n = S_a / |S_a|); d, Sn, v, m (n_node, 3); kappa (n_node,) [N mm]; tied (k,) node indices; e_node (k,)."""
    for j in prange(tied.shape[0]):
        a = tied[j]
        Sm = math.sqrt(Sn[a, 0] ** 2 + Sn[a, 1] ** 2 + Sn[a, 2] ** 2)
        n0, n1, n2 = Sn[a, 0] / Sm, Sn[a, 1] / Sm, Sn[a, 2] / Sm
        d0, d1, d2 = d[a, 0], d[a, 1], d[a, 2]
        k = kappa[a]
        dot = d0 * n0 + d1 * n1 + d2 * n2
        e_node[j] = k * (1.0 - dot)
        v[a, 0] = -k * (d0 - dot * n0) / Sm
        v[a, 1] = -k * (d1 - dot * n1) / Sm
        v[a, 2] = -k * (d2 - dot * n2) / Sm
        m[a, 0] = -k * (d1 * n2 - d2 * n1)
        m[a, 1] = -k * (d2 * n0 - d0 * n2)
        m[a, 2] = -k * (d0 * n1 - d1 * n0)


@njit_parallel
def tie_forces(x, conn, mask, v, fe):
    """fe (n_el, 4, 3) += dW/dx through S_e: u = sum of v over the element's distinct nodes; slot 3 gets
    B x u / 2, slot 1 minus it, slot 4 u x A / 2, slot 2 minus it (A = x_3 - x_1, B = x_4 - x_2)."""
    for e in prange(conn.shape[0]):
        u0 = 0.0
        u1 = 0.0
        u2 = 0.0
        for a in range(4):
            n = conn[e, a]
            u0 += mask[e, a] * v[n, 0]
            u1 += mask[e, a] * v[n, 1]
            u2 += mask[e, a] * v[n, 2]
        i0, i1, i2, i3 = conn[e, 0], conn[e, 1], conn[e, 2], conn[e, 3]
        A0, A1, A2 = x[i2, 0] - x[i0, 0], x[i2, 1] - x[i0, 1], x[i2, 2] - x[i0, 2]
        B0, B1, B2 = x[i3, 0] - x[i1, 0], x[i3, 1] - x[i1, 1], x[i3, 2] - x[i1, 2]
        p0, p1, p2 = 0.5 * (B1 * u2 - B2 * u1), 0.5 * (B2 * u0 - B0 * u2), 0.5 * (B0 * u1 - B1 * u0)
        q0, q1, q2 = 0.5 * (u1 * A2 - u2 * A1), 0.5 * (u2 * A0 - u0 * A2), 0.5 * (u0 * A1 - u1 * A0)
        fe[e, 2, 0] += p0
        fe[e, 2, 1] += p1
        fe[e, 2, 2] += p2
        fe[e, 0, 0] -= p0
        fe[e, 0, 1] -= p1
        fe[e, 0, 2] -= p2
        fe[e, 3, 0] += q0
        fe[e, 3, 1] += q1
        fe[e, 3, 2] += q2
        fe[e, 1, 0] -= q0
        fe[e, 1, 1] -= q1
        fe[e, 1, 2] -= q2


# ----------------------------------------------------------------------------------------------------------------
# Group
# ----------------------------------------------------------------------------------------------------------------

class ShellGroup:
    """Shells (or membranes) of one section. The engine calls ``update(x, v)`` then ``add_forces(f_int)``; groups
    with directors (``rotational``) read and write the run's rotational state given to ``bind``."""

    nodes_per_element = 4
    solid = False

    def __init__(self, name, section, X, conn, ids, material, params, rho, cell_type, orientation=None):
        from fdeck.engine.gather import node_slots

        self.name, self.section, self.material = name, section, material
        self.formulation = section.formulation
        self.cell_type = cell_type
        conn = np.asarray(conn, np.int64)
        if conn.shape[1] == 3:  # triangle -> degenerate quadrilateral (third node repeated)
            conn = np.column_stack([conn, conn[:, 2]])
        self.conn, self.ids = np.ascontiguousarray(conn), ids
        n_el = len(conn)
        self.rotational = section.formulation != "membrane"
        self.has_dir = self.rotational
        h = section.thickness
        self.h = h
        if section.formulation == "ts":
            z, wz = through_thickness(section.integration, section.points, h)
        else:
            z, wz = np.zeros(1), np.array([h])
        self.z, self.wz = z, wz
        self.Xe = X[self.conn]
        if orientation is None:
            from fdeck.compile.orientation import element_orientation

            orientation = element_orientation(section.orientation, n_el)
        self.e1, self.e2, self.N, bad = local_bases(self.Xe, orientation)
        if bad.any():
            raise CompileError([(("orientation", "reference"), f"reference direction is normal to {int(bad.sum())} "
                                 f"elements, ids {ids[bad][:10].tolist()}")])
        # material frames per Gauss point: rows warp, weft, normal
        self.frame = np.ascontiguousarray(np.stack([self.e1, self.e2, self.N], axis=2).reshape(n_el * 4, 3, 3))
        self.params = np.broadcast_to(params[0], (n_el * 4, params.shape[1]))
        self.rho = np.ascontiguousarray(rho, float)
        n_z = len(z)
        self.F = np.zeros((n_el, 4, n_z, 3, 3))
        self.F[:] = np.eye(3)
        self.P = np.zeros_like(self.F)
        self.psi = np.zeros((n_el, 4, n_z))
        self.modulus = np.zeros((n_el, 4, n_z, 3))
        self.state = np.zeros((n_el * 4, n_z, material.n_state))
        self.J = np.ones((n_el, 4))
        self.fe = np.zeros((n_el, 4, 3))
        self.ge = np.zeros((n_el, 4, 3))
        self.me = np.zeros((n_el, 4, 3))
        self.energy = np.zeros((n_el, 3))  # per element: the law's, bending, transverse shear [mJ]
        self.e_b, self.e_s = self.energy[:, 1], self.energy[:, 2]  # views
        self.dt_e = np.zeros(n_el)
        self.ptr, self.slots = node_slots(self.conn, len(X))
        self._evaluate_material()
        self.modulus_rest = self.modulus.copy()
        self.rot = None
        self._d_dummy = np.zeros((1, 3))
        self.detJ_min = np.linalg.norm(np.cross(np.einsum("ga,eai->egi", DN_GP[:, :, 0], self.Xe),
                                                np.einsum("ga,eai->egi", DN_GP[:, :, 1], self.Xe)), axis=-1).min(1)
        # ledger: the whole stored energy, and the shares of bending and transverse shear where the section has them
        parts = ("bending_energy", "transverse_shear_energy") if self.formulation == "sm" else \
            ("transverse_shear_energy",) if self.formulation == "ts" else ()
        self.kn = float(getattr(section, "normal_stiffness", 0.0)) if self.rotational else 0.0
        self.e_n = 0.0  # director-normal energy [mJ] (``normal_stiffness``)
        if self.kn > 0.0:
            parts += ("director_normal_energy",)
        self.terms = (Term("strain_energy", STORED),) + tuple(Term(n, PART) for n in parts)
        if not self.has_dir:  # membrane: reference geometry from the element alone
            self._prepare(None)

    # -- reference state -------------------------------------------------------------------------------
    def add_normals(self, acc, mag):
        """Add area-weighted element normals at the element's distinct nodes (compile: nodal directors)."""
        area = self._areas()
        nA = self.N.mean(axis=1) * area[:, None]
        tri = self.conn[:, 2] == self.conn[:, 3]
        for a in range(4):
            use = np.ones(len(self.conn), bool) if a < 3 else ~tri
            np.add.at(acc, self.conn[use, a], nA[use])
            np.add.at(mag, self.conn[use, a], area[use])

    def flipped_elements(self, d0):
        """Ids of elements whose normal points against the averaged directors of their nodes."""
        Dbar = np.einsum("ga,eai->egi", N_GP, d0[self.conn])
        return self.ids[(np.einsum("egi,egi->eg", Dbar, self.N) <= 0).any(axis=1)]

    def set_directors(self, d0):
        """Reference arrays that depend on the nodal directors d0 (n_node, 3)."""
        self._prepare(d0[self.conn])

    def _areas(self):
        J = np.linalg.norm(np.cross(np.einsum("ga,eai->egi", DN_GP[:, :, 0], self.Xe),
                                    np.einsum("ga,eai->egi", DN_GP[:, :, 1], self.Xe)), axis=-1)
        return J.sum(axis=1)

    def _prepare(self, De):
        """Reference arrays from the nodal reference directors De (n_el, 4, 3), or None for membranes (the unit
        normal at each Gauss point stands for the director, without derivative)."""
        sec = self.section
        n_el = len(self.conn)
        G3 = None
        if De is None:
            G3 = self.N
            De = np.repeat(self.N.mean(axis=1)[:, None, :], 4, axis=1)
        self.T, self.tau, det = level_maps(self.Xe, De, self.e1, self.e2, self.z, G3)
        self.w = np.ascontiguousarray(det * self.wz[None, None, :])
        T0, tau0, det0 = level_maps(self.Xe, De, self.e1, self.e2, np.zeros(1), G3)
        self.T0, self.tau0 = np.ascontiguousarray(T0[:, :, 0]), np.ascontiguousarray(tau0[:, :, 0])
        self.aw = np.ascontiguousarray(det0[:, :, 0])
        self.detJ_min = self.aw.min(axis=1)
        self.area = self.aw.sum(axis=1)
        self.V0 = self.area * self.h
        # local shape-function derivatives c_gak = sum_j T0_kj dN_a,j (n_el, 4 gp, 4 nodes, 2)
        self.c0 = np.einsum("egkj,gaj->egak", self.T0, DN_GP)
        # reference bending strain and MITC tying strains (zero for flat elements with normal directors)
        Dxi = np.einsum("gaj,eai->egji", DN_GP, De)
        B = np.einsum("egkj,egji->egki", self.T0, Dxi)
        ek = np.stack([self.e1, self.e2], axis=2)
        AB = np.einsum("egki,egli->egkl", ek, B)
        self.k0 = np.ascontiguousarray(np.stack([AB[:, :, 0, 0], AB[:, :, 1, 1],
                                                 0.5 * (AB[:, :, 0, 1] + AB[:, :, 1, 0])], axis=2))
        p, q = EDGES[:, 0], EDGES[:, 1]
        self.gam0 = np.ascontiguousarray(0.25 * np.einsum("eki,eki->ek", self.Xe[:, q] - self.Xe[:, p],
                                                          De[:, p] + De[:, q]))
        # lumped masses per slot [t] / rho: h integral N_a dA
        self.mass_shape = self.h * np.einsum("ga,eg->ea", N_GP, self.aw)
        self._lengths()
        # section stiffnesses
        M0 = np.einsum("l,eglk->egk", self.wz / self.h, self.modulus_rest).max(axis=(1, 2))
        self.bend = np.zeros((n_el, 3))
        self.ks = np.zeros(n_el)
        if sec.formulation == "sm":
            EI, GI = sec.bending_stiffness, sec.twisting_stiffness
            self.bend[:] = [EI, EI, GI]
            Dmax = max(EI, GI)
            self.ks = np.minimum(sec.transverse_shear_penalty * 12.0 * Dmax / self.area, BETA_SHEAR * M0 * self.h)
        elif sec.formulation == "ts":
            self.ks[:] = sec.shear_correction * sec.transverse_shear_modulus * self.h
        self._inertia_and_step_constants(De, M0)

    def _lengths(self):
        """L0 (n_el,) smallest height [mm]; inv_len2 (n_el, 2) = 1 / L_k^2 along warp and weft."""
        b = np.einsum("eg,egak->eak", self.aw, self.c0) / self.area[:, None, None]  # uniform gradients per slot
        tri = self.conn[:, 2] == self.conn[:, 3]
        b[tri, 2] += b[tri, 3]
        b[tri, 3] = 0.0
        self.inv_len2 = np.ascontiguousarray(np.einsum("eak,eak->ek", b, b))
        Xe = self.Xe
        edges = np.linalg.norm(Xe[:, [1, 2, 3, 0]] - Xe, axis=-1).max(axis=1)
        self.L0 = np.where(tri, 2.0, 1.0) * self.area / edges

    def _inertia_and_step_constants(self, De, M0):
        """Rotational inertia radius r_e^2 [mm^2] and the constant step term C (n_el,) (see the module docstring)."""
        n_el = len(self.conn)
        m = self.mass_shape  # per unit density
        # Frobenius bounds (per unit density) of the rotational and translational stiffness parts
        Dmax = np.maximum(self.bend[:, 0], np.maximum(self.bend[:, 1], 2.0 * self.bend[:, 2]))
        c2 = np.einsum("egak,egak->ega", self.c0, self.c0)
        Kb = 1.5 * Dmax * np.einsum("eg,ega,ea->e", self.aw, c2, 1.0 / m)
        cx, cd = self._shear_b(De)
        Ksx = self.ks * np.einsum("eg,egkai,egkai,ea->e", self.aw, cx, cx, 1.0 / m)
        Ksd = self.ks * np.einsum("eg,egkai,egkai,ea->e", self.aw, cd, cd, 1.0 / m)
        lam_mem = 4.0 * self._s(np.einsum("l,eglk->egk", self.wz / self.h, self.modulus_rest))  # times rho
        r2 = np.full(n_el, self.h**2 / 12.0)
        if self.rotational:
            r2 = np.maximum(r2, (Kb + Ksd) / (BETA * lam_mem))
            zmax2 = float(np.max(self.z**2))
            if zmax2 > 0:
                r2 = np.maximum(r2, zmax2 / BETA)
        self.r2 = r2
        self.fz = np.ascontiguousarray(1.0 + self.z[None, :] ** 2 / r2[:, None]) if self.rotational else \
            np.ones((n_el, len(self.z)))
        if self.kn > 0.0:
            # director-normal tie: rotational stiffness k_n A_a on I_a = rho h A_a r_e^2, and a translational one of
            # about k_n A_a / L^2 through the normal's dependence on the nodes (bounded with a factor 4)
            r2 = np.maximum(r2, self.kn / (self.h * BETA * lam_mem))
            Ksx = Ksx + 4.0 * self.kn / (self.h * self.L0**2)
            Ksd = Ksd + self.kn / self.h
            self._normal_constants()
        self.C = np.ascontiguousarray((Kb + Ksd) / r2 + Ksx)
        self.added_rotational_inertia = float(r2.sum() / (n_el * self.h**2 / 12.0) - 1.0) if self.rotational else 0.0

    def _normal_constants(self):
        """kappa (n_node,) = k_n A_a [N mm] per node of the group; slot mask (n_el, 4): 0 on the repeated node of a
        triangle (each distinct node of an element counted once)."""
        n_node = len(self.ptr) - 1
        self.slot_mask = np.ones(self.conn.shape)
        self.slot_mask[self.conn[:, 2] == self.conn[:, 3], 3] = 0.0
        area = np.zeros(n_node)
        np.add.at(area, self.conn.ravel(), (self.mass_shape / self.h * self.slot_mask).ravel())
        self.kappa = self.kn * area
        self.tied = np.nonzero(area > 0.0)[0]
        self.m_n = np.zeros((n_node, 3))
        self._slot_S = np.zeros(self.conn.shape + (3,))
        self._Sn = np.zeros((n_node, 3))
        self._v = np.zeros((n_node, 3))
        self._e_node = np.zeros(len(self.tied))

    def _normal_tie(self, x, d):
        """Energy k_n A_a (1 - d_a . n_a) summed over the group's nodes, n_a = S_a / |S_a| the unit nodal normal,
        S_a the sum of the vector areas S_e = (x_3 - x_1) x (x_4 - x_2) / 2 of the section's elements at node a
        (exact for a flat quadrilateral and for a triangle as a degenerate one). Adds its nodal forces dW/dx into
        fe (chain rule through S_e: dS_e = (dA x B + A x dB) / 2 with A = x_3 - x_1, B = x_4 - x_2) and keeps the
        nodal moments d_a x dW/dd_a = -kappa_a d_a x n_a in m_n (n_node, 3) [N mm]."""
        tie_areas(x, self.conn, self.slot_mask, self._slot_S)
        self._Sn.fill(0.0)
        gather_add(self._slot_S, self.ptr, self.slots, self._Sn)
        tie_nodes(d, self._Sn, self.kappa, self.tied, self._v, self.m_n, self._e_node)
        self.e_n = float(self._e_node.sum())
        tie_forces(x, self.conn, self.slot_mask, self._v, self.fe)

    def _shear_b(self, De):
        """Rest-state MITC maps at each Gauss point: cx, cd (n_el, 4 gp, 2 k, 4 nodes, 3) with
        d gamma_k = sum_a cx_ka . dx_a + cd_ka . dd_a."""
        n_el = len(self.conn)
        p, q = EDGES[:, 0], EDGES[:, 1]
        Dm = 0.5 * (De[:, p] + De[:, q])  # (n_el, 4 edges, 3)
        Xd = 0.5 * (self.Xe[:, q] - self.Xe[:, p])
        cx = np.zeros((n_el, 4, 2, 4, 3))
        cd = np.zeros((n_el, 4, 2, 4, 3))
        for g, (xi, eta) in enumerate(GAUSS):
            # covariant gamma_j as sum over edges phi_{j,edge} gamma_edge
            phi = {0: (0, 0.5 * (1 - eta)), 2: (0, 0.5 * (1 + eta)), 3: (1, 0.5 * (1 - xi)), 1: (1, 0.5 * (1 + xi))}
            for edge, (j, ph) in phi.items():
                for k in range(2):
                    t = self.T0[:, g, k, j][:, None] * ph
                    cx[:, g, k, q[edge]] += t * 0.5 * Dm[:, edge]
                    cx[:, g, k, p[edge]] -= t * 0.5 * Dm[:, edge]
                    cd[:, g, k, p[edge]] += t * 0.5 * Xd[:, edge]
                    cd[:, g, k, q[edge]] += t * 0.5 * Xd[:, edge]
        return cx, cd

    def _s(self, M):
        """s (n_el,) of ``element_dt`` from per-point moduli M (n_el, 4, 2 or 3) [MPa]."""
        M1, M2, M3 = M[:, :, 0].max(axis=1), M[:, :, 1].max(axis=1), M[:, :, 2].max(axis=1)
        lo = np.minimum(np.minimum(M1, M2), M3)
        return lo / self.L0**2 + np.maximum((M1 - lo) * self.inv_len2[:, 0], (M2 - lo) * self.inv_len2[:, 1])

    # -- per cycle -------------------------------------------------------------------------------------
    def bind(self, rotations) -> None:
        self.rot = rotations

    def _evaluate_material(self):
        n_el, n_z = len(self.conn), len(self.z)
        F = self.F.reshape(n_el * 4, n_z, 3, 3)
        self.material.evaluate(F, self.frame, self.params, self.state, self.P.reshape(F.shape),
                               self.psi.reshape(n_el * 4, n_z), self.modulus.reshape(n_el * 4, n_z, 3))

    def update(self, x, v):
        d = self.rot.d if self.has_dir else self._d_dummy
        kinematics(x, d, self.conn, self.T, self.tau, self.z, self.e1, self.e2, self.N, self.T0, self.tau0,
                   self.has_dir, self.F, self.J)
        self._evaluate_material()
        forces(x, d, self.conn, self.T, self.tau, self.z, self.w, self.e1, self.e2, self.P, self.psi, self.T0,
               self.tau0, self.aw, self.k0, self.bend, self.ks, self.gam0, self.has_dir, self.fe, self.ge, self.me,
               self.energy)
        if self.kn > 0.0:
            self._normal_tie(x, d)

    def add_forces(self, f_int):
        gather_add(self.fe, self.ptr, self.slots, f_int)
        if self.has_dir:
            gather_add(self.me, self.ptr, self.slots, self.rot.m_int)
            if self.kn > 0.0:
                self.rot.m_int += self.m_n

    def term_values(self) -> tuple[float, ...]:
        """Stored energy [mJ] (the law's sum w psi + bending + transverse shear), then the shares in ``terms``."""
        share = {"bending_energy": self.e_b, "transverse_shear_energy": self.e_s, "director_normal_energy": self.e_n}
        return (float(self.energy.sum()) + self.e_n,) + tuple(float(np.sum(share[t.name])) for t in self.terms[1:])

    def set_density(self, rho: np.ndarray) -> None:
        """Densities (n_el,) [t/mm^3] of the step, copied: the group's own array (mass tracking raises it during a
        step), never an alias of the step plan's (which a checkpoint saves and restores separately)."""
        self.rho = np.array(rho, float)

    def stable_dt(self) -> float:
        element_dt(self.modulus, self.wz / self.h, self.fz, self.L0, self.inv_len2, self.C, self.rho, self.dt_e)
        return float(self.dt_e.min())

    def rest_dt(self, rho: np.ndarray) -> np.ndarray:
        out = np.empty(len(self.conn))
        rho = np.ascontiguousarray(rho, float)
        element_dt(self.modulus_rest, self.wz / self.h, self.fz, self.L0, self.inv_len2, self.C, rho, out)
        return out

    def worst_jacobian(self) -> tuple[float, int]:
        flat = int(np.argmin(self.J))
        return float(self.J.flat[flat]), int(self.ids[flat // 4])

    def mass(self, rho: np.ndarray) -> np.ndarray:
        """Lumped masses per slot (n_el, 4) [t] with densities rho (n_el,): rho h integral N_a dA."""
        return np.asarray(rho, float)[:, None] * self.mass_shape

    def inertia(self, rho: np.ndarray) -> np.ndarray:
        """Lumped rotational inertia per slot (n_el, 4) [t mm^2] with densities rho (n_el,): m_a r_e^2."""
        return self.mass(rho) * self.r2[:, None]

    def director_forces(self, n_node: int) -> np.ndarray:
        """(n_node, 3) sum of the element director forces dW/dd at each node [N mm] (tests, diagnostics)."""
        out = np.zeros((n_node, 3))
        np.add.at(out, self.conn.ravel(), self.ge.reshape(-1, 3))
        return out

    # -- output ----------------------------------------------------------------------------------------
    def cell_fields(self, idx=None, names=None) -> dict[str, np.ndarray]:
        """Per-element output averaged over points: Cauchy stress (n, 6) [MPa], strain-energy density [MPa], area
        ratio J, bending and transverse-shear energy densities [MPa], and the law's diagnostics. ``names``: as
        ``Hex8Group.cell_fields`` (the stress and the diagnostics only where asked for)."""
        idx = np.arange(len(self.conn)) if idx is None else np.asarray(idx)
        F, w = self.F[idx], self.w[idx]
        wn = w / w.sum(axis=(1, 2), keepdims=True)
        V0 = self.V0[idx]
        out = {}
        if names is None or "stress" in names:
            sigma = np.einsum("eglij,eglkj->eglik", self.P[idx], F) / np.linalg.det(F)[..., None, None]
            s = np.einsum("egl,eglij->eij", wn, sigma)
            out["stress"] = np.stack([s[:, 0, 0], s[:, 1, 1], s[:, 2, 2], s[:, 0, 1], s[:, 1, 2], s[:, 0, 2]], axis=1)
        out["strain_energy_density"] = (np.einsum("egl,egl->e", w, self.psi[idx]) + self.e_b[idx] + self.e_s[idx]) / V0
        out["J"] = self.J[idx].mean(axis=1)
        parts = [t.name for t in self.terms]
        if "bending_energy" in parts:
            out["bending_energy_density"] = self.e_b[idx] / V0
        if "transverse_shear_energy" in parts:
            out["transverse_shear_energy_density"] = self.e_s[idx] / V0
        if names is None or not set(names).isdisjoint(self.material.diagnostics):
            n, n_z = len(idx), len(self.z)
            # point (corner g, level l) of element e reads the frame and law of its corner, row 4 e + g
            src = np.repeat(4 * np.asarray(idx)[:, None] + np.arange(4)[None, :], n_z, axis=1)
            out.update(diagnostics.averaged(self.material, F.reshape(n, 4 * n_z, 3, 3), self.frame, self.params, src,
                                            wn.reshape(n, 4 * n_z)))
        return out


def build(name, section, X, conn, ids, material, params, orientation, rho, cell_type):
    """Registry hook: a ShellGroup for one shell section (its own per-point frames from the element orientation)."""
    return ShellGroup(name, section, X, conn, ids, material, params, rho, cell_type, orientation)


for _name in ("sm", "ts", "membrane"):
    register_formulation(FormulationKind(_name, build, 4))
