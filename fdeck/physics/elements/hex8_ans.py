"""Eight-node hexahedron with assumed natural shear strains (formulation ``ans``): bends without shear locking.

Why this element. In a fabric the fibres are stiff in tension, soft (1 % with [P]'s law) in compression, and the
transverse shears are soft or, for the weft of 3WEAVE, comparatively stiff. When a 2x2x2-point hexahedron bends,
its bending mode u = xi zeta e_x carries a parasitic shear strain proportional to xi at the Gauss points, whose
energy ~ G (a/h)^2 against the bending energy ~ E_fibre: the element locks as soon as G / E_fibre is not small,
which is the weft strip (43 MPa transverse shear against a few MPa of effective bending modulus in compression).
Alternatives weighed:

* selective (per-mode) integration of the fabric energies would have to reach inside every material law (the
  modes are the law's, not the element's) and does not exist for a general law (``neo_hookean``, ``elastic``);
* one-point integration with hourglass control (``reduced``) does not lock but its bending stiffness is the
  hourglass spring's, a tuning coefficient, not the material's;
* enhanced assumed strains (Simo-Rifai 1990, Simo-Armero 1992) cure shear locking too but add 9-12 internal
  parameters per element, condensed per cycle (a 9 x 9 solve per element) or carried as extra dynamic unknowns,
  and are known to hourglass in compression at finite strain (Wriggers-Reese 1996);
* a solid-shell (Vu-Quoc and Tan 2003, Schwarze and Reese 2009) needs a thickness direction chosen per element;
  fabric blocks are also meshed as solids bent about any axis.

So the assumed-strain idea of Dvorkin and Bathe (A continuum mechanics based four-node shell element for general
nonlinear analysis, 1984) and of Belytschko and Bindeman (Assumed strain stabilization of the eight node hexahedral
element, 1993), applied to every shear pair: the covariant shear strain E_ij (i != j, natural axes xi_i) at a Gauss
point is taken on the line through that point where xi_i = xi_j = 0, i.e. it keeps its variation along the third
axis only and loses the parasitic one along xi_i and xi_j. Normal strains stay fully integrated. To keep the patch
test exact on distorted elements the substitution is applied to the non-affine part only: with F0 = sum_a x_a (x) b_a
the uniform gradient (exact for every affine motion), G_i = dX/dxi_i, g_i = dx/dxi_i, h_i = F0 G_i,

    2 E~_ij(q) = [g_i.g_j - h_i.h_j](p_ij(q)) + [h_i.h_j - G_i.G_j](q),       C~ = I + 2 J0^-T E~ J0^-1 at q,

which equals the true strain at q for every affine motion (then g = h everywhere). The modification this makes,
K_q = C~_q - C_q, is then made mean-free over the element: C~_q = C_q + K_q - K_bar, K_bar = sum_r w_r K_r / V0.
Without it a uniform stress still does work on the sampled shears of a non-affine variation wherever the natural
components J0^-1 S J0^-T differ between points (any non-parallelepiped element), and the interior node of a
distorted patch carried 3.8e-2 of the largest force (measured 2026-11-26); with it sum_q w_q S : d(K_q - K_bar) = 0
for every uniform S, the mean-dilatation idea of B-bar applied to the shear modification. On parallelepipeds K_bar
vanishes to first order in the strain (the parasitic shears are odd in the natural coordinates), so block meshes
bend as before. Every term is a dot product of current vectors, so C~ is objective. The material sees
F~ = F Rc^-1 R~, Rc and R~ the upper Cholesky factors of C = F^T F and C~ (F~^T F~ = C~, F~ = F when C~ = C,
F~ -> Q F~ when F -> Q F), so any law of F (fabric_hyper, linear_elastic, neo_hookean) serves unchanged;
W = sum_q w_q psi(C~_q) and the forces are its exact derivative (``forces_ans``): dW = sum_q w_q (F S : dF +
S~_ij dDelta_ij) with S = F~^-1 P~ and S~ = J0^-1 (S - S_bar) J0^-T, S_bar the element's volume mean of S (the
mean-free modification's share).

Known limits: normal strains are fully integrated, so nearly incompressible isotropic laws lock volumetrically as
with ``full`` (fabrics are compressible: use ``fbar`` for rubber); C~ keeps the true normal strain along the
thickness but not the shear part of it, so where the true transverse shear exceeds the assumed one (an element
whose thickness edges fan out, as in bending) the thickness and volume read from C~ exceed the true ones, and an
edge can be crushed through the thickness without the law's compaction seeing it (``ans_tbar`` gives its material
the true thickness stretch: ``hex8_ans_fbar``, ``test_thickness_crush``); a trapezoidal (curved) element through a thin
thickness keeps the thickness-strain locking that solid-shells cure by ANS on E_33; an extremely distorted state
whose C~ is not positive definite gives nan (reported by the engine's inversion monitor).
Units as in ``hex8``: x [mm], forces [N], stresses [MPa].
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.jit import njit_inline, njit_parallel, prange
from fdeck.physics.elements.hex8 import GAUSS_2, Hex8Group, _gradient, shape_gradients_local
from fdeck.registry import FormulationKind, register_formulation

PAIRS = ((0, 1), (1, 2), (0, 2))
"""Shear pairs (i, j) of natural axes; the third axis of pair k is ``3 - i - j``."""


def sampling_points() -> tuple[np.ndarray, np.ndarray]:
    """Sampling points (6, 3) of the assumed shears and, per Gauss point and pair, the index of its point (8, 3).

    Point 2k + s belongs to pair k: the natural coordinates i and j of the pair are zero, the third is -c (s = 0) or
    +c (s = 1), c = 1/sqrt(3), the Gauss coordinate: the line through the Gauss point along the third axis.
    """
    c = 1.0 / math.sqrt(3.0)
    pts = np.zeros((6, 3))
    index = np.zeros((8, 3), np.int64)
    for k, (i, j) in enumerate(PAIRS):
        third = 3 - i - j
        pts[2 * k, third], pts[2 * k + 1, third] = -c, c
        for q in range(8):
            index[q, k] = 2 * k + (1 if GAUSS_2[q, third] > 0 else 0)
    return pts, index


def prepare_ans(X: np.ndarray, conn: np.ndarray) -> dict:
    """Reference arrays of the assumed strains. X (n_node, 3), conn (n_el, 8).

    Returns dxi_s (6, 8, 3) the natural shape gradients at the sampling points, index (8, 3) (``sampling_points``),
    Jinv (n_el, 8, 3, 3) inverse reference Jacobians dxi/dX at the Gauss points, and Gq (n_el, 8, 3, 3), Gs
    (n_el, 6, 3, 3) the reference base vectors as columns G[:, i] = dX/dxi_i [mm] at the Gauss and sampling points.
    """
    pts, index = sampling_points()
    dxi_s = shape_gradients_local(pts)
    xe = X[conn]
    Gq = np.einsum("eai,qaj->eqij", xe, shape_gradients_local(GAUSS_2))
    Gs = np.einsum("eai,saj->esij", xe, dxi_s)
    return dict(dxi_s=dxi_s, index=index, Jinv=np.ascontiguousarray(np.linalg.inv(Gq)),
                Gq=np.ascontiguousarray(Gq), Gs=np.ascontiguousarray(Gs))


EIGHT = np.arange(8).reshape(1, 8)
"""The identity row of slots: ``hex8._gradient`` reads the element's own gathered nodes through it."""

CHUNK = 32
"""Elements per scratch set: the kernels allocate their scratch arrays once per CHUNK elements, not per element
(when the kinematics allocated its 13 per element, that cost a tenth of it: 0.93 -> 0.82 us per element,
``benchmarks/kernel_parts.py ans_tbar fabric_hyper_3weave``, bitwise the same)."""


@njit_inline
def _chol_upper(c00, c01, c02, c11, c12, c22):
    """Upper triangular R with R^T R = C for the upper triangle of a symmetric C, as scalars (r00, r01, r02, r11,
    r12, r22) followed by the reciprocals of R's diagonal (one division each, then multiplications); nan when C is
    not positive definite. Scalars, not arrays: a 3x3 scratch array is memory the compiler must reload after every
    store to another array it cannot prove distinct (docs/kernels.md, item 13)."""
    r00 = math.sqrt(c00)
    i0 = 1.0 / r00
    r01 = c01 * i0
    r02 = c02 * i0
    r11 = math.sqrt(c11 - r01 * r01)
    i1 = 1.0 / r11
    r12 = (c12 - r01 * r02) * i1
    r22 = math.sqrt(c22 - r02 * r02 - r12 * r12)
    return r00, r01, r02, r11, r12, r22, i0, i1, 1.0 / r22


@njit_inline
def _natural(A, G, e, s, i, j):
    """G[e, s][:, i] . A . G[e, s][:, j] for a (3, 3) A and base-vector columns G (n_el, n_s, 3, 3), in place."""
    acc = 0.0
    for k in range(3):
        acc += G[e, s, k, i] * (A[k, 0] * G[e, s, 0, j] + A[k, 1] * G[e, s, 1, j] + A[k, 2] * G[e, s, 2, j])
    return acc


@njit_inline
def _inv3_at(A, e, q):
    """The nine components of A[e, q]^-1 (A (n_el, n_qp, 3, 3)) as scalars, row by row: the cofactors over
    ``hex8._det_at``'s determinant, one division (``tensor.inv3``'s arithmetic)."""
    a00, a01, a02 = A[e, q, 0, 0], A[e, q, 0, 1], A[e, q, 0, 2]
    a10, a11, a12 = A[e, q, 1, 0], A[e, q, 1, 1], A[e, q, 1, 2]
    a20, a21, a22 = A[e, q, 2, 0], A[e, q, 2, 1], A[e, q, 2, 2]
    r = 1.0 / (a00 * (a11 * a22 - a12 * a21) - a01 * (a10 * a22 - a12 * a20) + a02 * (a10 * a21 - a11 * a20))
    return ((a11 * a22 - a12 * a21) * r, (a02 * a21 - a01 * a22) * r, (a01 * a12 - a02 * a11) * r,
            (a12 * a20 - a10 * a22) * r, (a00 * a22 - a02 * a20) * r, (a02 * a10 - a00 * a12) * r,
            (a10 * a21 - a11 * a20) * r, (a01 * a20 - a00 * a21) * r, (a00 * a11 - a01 * a10) * r)


@njit_inline
def _point_mean(Aq, w, e, out):
    """out (3, 3) = sum_q w[e, q] Aq[q] / sum_q w[e, q]: the volume mean over element e's points of Aq (8, 3, 3)."""
    vol = 0.0
    for i in range(3):
        for j in range(3):
            out[i, j] = 0.0
    for q in range(Aq.shape[0]):
        wq = w[e, q]
        vol += wq
        for i in range(3):
            for j in range(3):
                out[i, j] += wq * Aq[q, i, j]
    for i in range(3):
        for j in range(3):
            out[i, j] /= vol


@njit_parallel
def kinematics_ans(x, conn, b, dN, w, dxi_s, index, Jinv, Gq, Gs, F, J, Fans, F0s, gs):
    """True F (n_el, 8, 3, 3), J = det F (n_el, 8) and the material's F~ (n_el, 8, 3, 3) with F~^T F~ = C~; keeps
    for the forces F0s (n_el, 3, 3), the uniform gradient, and gs (n_el, 6, 3, 2), the current base vectors
    g_i, g_j of each sampling point's pair [mm]. w (n_el, 8) point volumes [mm^3]: C~_q = C_q + K_q - K_bar with
    K_q = J0^-T Delta_q J0^-1 the assumed-shear modification and K_bar = sum_r w_r K_r / V0 its element mean."""
    n_el = conn.shape[0]
    for chunk in prange((n_el + CHUNK - 1) // CHUNK):
        xe = np.empty((8, 3))
        C0 = np.empty((3, 3))
        Cq = np.empty((8, 3, 3))
        Kq = np.empty((8, 3, 3))
        Kbar = np.empty((3, 3))
        W = np.empty((3, 3))
        T = np.empty((3, 3))
        A = np.empty(6)
        for e in range(chunk * CHUNK, min(n_el, (chunk + 1) * CHUNK)):
            _kinematics_element(x, conn, b, dN, w, dxi_s, index, Jinv, Gq, Gs, F, J, Fans, F0s, gs, e,
                                xe, C0, Cq, Kq, Kbar, W, T, A)


@njit_inline
def _kinematics_element(x, conn, b, dN, w, dxi_s, index, Jinv, Gq, Gs, F, J, Fans, F0s, gs, e,
                        xe, C0, Cq, Kq, Kbar, W, T, A):
    """``kinematics_ans`` for element e, with the chunk's scratch: xe (8, 3) the element's nodes, Cq, Kq (8, 3, 3),
    A (6,), the rest (3, 3); Cq, Kq and Kbar hold their upper triangles only (symmetric; the lower ones are left
    unwritten and never read). The element's nodes are gathered once and what stays within a point is kept in
    scalars; every value is formed by the same operations in the same order as before (docs/kernels.md, item 13).
    """
    for a in range(8):
        n = conn[e, a]
        xe[a, 0], xe[a, 1], xe[a, 2] = x[n, 0], x[n, 1], x[n, 2]
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for a in range(8):
                acc += xe[a, i] * b[e, a, j]
            F0s[e, i, j] = acc
    for i in range(3):
        for j in range(3):
            C0[i, j] = F0s[e, 0, i] * F0s[e, 0, j] + F0s[e, 1, i] * F0s[e, 1, j] + F0s[e, 2, i] * F0s[e, 2, j]
    # non-affine shear at the sampling points: g_i.g_j - G_i.C0.G_j
    for s in range(6):
        i, j = PAIRS[s // 2]
        for c in range(2):
            k = i if c == 0 else j
            for r in range(3):
                acc = 0.0
                for a in range(8):
                    acc += xe[a, r] * dxi_s[s, a, k]
                gs[e, s, r, c] = acc
        A[s] = (gs[e, s, 0, 0] * gs[e, s, 0, 1] + gs[e, s, 1, 0] * gs[e, s, 1, 1] + gs[e, s, 2, 0] * gs[e, s, 2, 1]
                - _natural(C0, Gs, e, s, i, j))
    for q in range(8):
        f00, f01, f02, f10, f11, f12, f20, f21, f22 = _gradient(xe, EIGHT, 0, dN, e, q)
        F[e, q, 0, 0], F[e, q, 0, 1], F[e, q, 0, 2] = f00, f01, f02
        F[e, q, 1, 0], F[e, q, 1, 1], F[e, q, 1, 2] = f10, f11, f12
        F[e, q, 2, 0], F[e, q, 2, 1], F[e, q, 2, 2] = f20, f21, f22
        J[e, q] = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
                   + f02 * (f10 * f21 - f11 * f20))
        c00 = f00 * f00 + f10 * f10 + f20 * f20
        c01 = f00 * f01 + f10 * f11 + f20 * f21
        c02 = f00 * f02 + f10 * f12 + f20 * f22
        c11 = f01 * f01 + f11 * f11 + f21 * f21
        c12 = f01 * f02 + f11 * f12 + f21 * f22
        c22 = f02 * f02 + f12 * f12 + f22 * f22
        Cq[q, 0, 0], Cq[q, 0, 1], Cq[q, 0, 2], Cq[q, 1, 1], Cq[q, 1, 2], Cq[q, 2, 2] = c00, c01, c02, c11, c12, c22
        W[0, 0], W[0, 1], W[0, 2] = c00 - C0[0, 0], c01 - C0[0, 1], c02 - C0[0, 2]
        W[1, 0], W[1, 1], W[1, 2] = c01 - C0[1, 0], c11 - C0[1, 1], c12 - C0[1, 2]
        W[2, 0], W[2, 1], W[2, 2] = c02 - C0[2, 0], c12 - C0[2, 1], c22 - C0[2, 2]
        # the natural correction Delta: zero diagonal, d01, d12, d02 off it
        d01 = A[index[q, 0]] - _natural(W, Gq, e, q, 0, 1)
        d12 = A[index[q, 1]] - _natural(W, Gq, e, q, 1, 2)
        d02 = A[index[q, 2]] - _natural(W, Gq, e, q, 0, 2)
        # K_q = Jinv^T Delta Jinv (T = Delta Jinv first); symmetric, and only its upper triangle is read
        for j in range(3):
            j0, j1, j2 = Jinv[e, q, 0, j], Jinv[e, q, 1, j], Jinv[e, q, 2, j]
            T[0, j] = 0.0 * j0 + d01 * j1 + d02 * j2
            T[1, j] = d01 * j0 + 0.0 * j1 + d12 * j2
            T[2, j] = d02 * j0 + d12 * j1 + 0.0 * j2
        for i in range(3):
            k0, k1, k2 = Jinv[e, q, 0, i], Jinv[e, q, 1, i], Jinv[e, q, 2, i]
            for j in range(i, 3):
                Kq[q, i, j] = k0 * T[0, j] + k1 * T[1, j] + k2 * T[2, j]
    _upper_mean(Kq, w, e, Kbar)
    for q in range(8):
        c00, c01, c02 = Cq[q, 0, 0], Cq[q, 0, 1], Cq[q, 0, 2]
        c11, c12, c22 = Cq[q, 1, 1], Cq[q, 1, 2], Cq[q, 2, 2]
        # C~ = C + K_q - K_bar and its upper Cholesky factor Ra, then C's factor Rc
        ra00, ra01, ra02, ra11, ra12, ra22, _, _, _ = _chol_upper(
            c00 + (Kq[q, 0, 0] - Kbar[0, 0]), c01 + (Kq[q, 0, 1] - Kbar[0, 1]), c02 + (Kq[q, 0, 2] - Kbar[0, 2]),
            c11 + (Kq[q, 1, 1] - Kbar[1, 1]), c12 + (Kq[q, 1, 2] - Kbar[1, 2]), c22 + (Kq[q, 2, 2] - Kbar[2, 2]))
        _, rc01, rc02, _, rc12, _, i0, i1, i2 = _chol_upper(c00, c01, c02, c11, c12, c22)
        # F~ = F M, M = Rc^-1 Ra by back substitution; M's lower triangle is zero but formed all the same, so that
        # a singular C (an infinite reciprocal) still makes all of F~ nan, as it always did
        m20, m21, m22 = 0.0 * i2, 0.0 * i2, ra22 * i2
        m10, m11, m12 = (0.0 - rc12 * m20) * i1, (ra11 - rc12 * m21) * i1, (ra12 - rc12 * m22) * i1
        m00 = (ra00 - rc01 * m10 - rc02 * m20) * i0
        m01 = (ra01 - rc01 * m11 - rc02 * m21) * i0
        m02 = (ra02 - rc01 * m12 - rc02 * m22) * i0
        for i in range(3):
            fi0, fi1, fi2 = F[e, q, i, 0], F[e, q, i, 1], F[e, q, i, 2]
            Fans[e, q, i, 0] = fi0 * m00 + fi1 * m10 + fi2 * m20
            Fans[e, q, i, 1] = fi0 * m01 + fi1 * m11 + fi2 * m21
            Fans[e, q, i, 2] = fi0 * m02 + fi1 * m12 + fi2 * m22


@njit_inline
def _upper_mean(Aq, w, e, out):
    """The upper triangle of out (3, 3) = sum_q w[e, q] Aq[q] / sum_q w[e, q], the volume mean over element e's
    points of Aq (8, 3, 3), read on its upper triangle only (``_point_mean``'s arithmetic)."""
    vol = 0.0
    for i in range(3):
        for j in range(i, 3):
            out[i, j] = 0.0
    for q in range(Aq.shape[0]):
        wq = w[e, q]
        vol += wq
        for i in range(3):
            for j in range(i, 3):
                out[i, j] += wq * Aq[q, i, j]
    for i in range(3):
        for j in range(i, 3):
            out[i, j] /= vol


@njit_parallel
def forces_ans(F, Fans, Pans, dN, w, b, dxi_s, index, Jinv, Gq, Gs, F0s, gs, fe):
    """fe (n_el, 8, 3) [N] = dW/dx of W = sum_q w_q psi(C~_q), from Pans = dpsi/dF~ (n_el, 8, 3, 3) [MPa].

    With S = F~^-1 P~ (second Piola-Kirchhoff stress of C~) and S~ = J0^-1 S J0^-T its natural components:
    dW = sum_q w_q S~ : dE~_nat, which collects into three parts: at each Gauss point F J0 diag(S~) J0^T (only the
    point's own normal strains remain) against dF; at each sampling point s the summed c_s = sum_q w_q S~_ij of the
    Gauss points on its line against d(g_i.g_j); and against the uniform gradient dF0 the affine corrections
    F0 [sum_q w_q J0 offdiag(S~) J0^T - sum_s c_s (G_i G_j^T + G_j G_i^T)].
    """
    n_el = fe.shape[0]
    for chunk in prange((n_el + CHUNK - 1) // CHUNK):
        T = np.empty((3, 3))
        B0 = np.empty((3, 3))
        cs = np.empty(6)
        Sq = np.empty((8, 3, 3))
        Sbar = np.empty((3, 3))
        for e in range(chunk * CHUNK, min(n_el, (chunk + 1) * CHUNK)):
            _forces_element(F, Fans, Pans, dN, w, b, dxi_s, index, Jinv, Gq, Gs, F0s, gs, fe, e, T, B0, cs, Sq, Sbar)


@njit_inline
def _forces_element(F, Fans, Pans, dN, w, b, dxi_s, index, Jinv, Gq, Gs, F0s, gs, fe, e, T, B0, cs, Sq, Sbar):
    """``forces_ans`` for element e, with the chunk's scratch: (3, 3) arrays but cs (6,) and Sq (8, 3, 3). What
    stays within a point is kept in scalars; every value is formed by the same operations in the same order as
    before (docs/kernels.md, item 13), the unused diagonal of w S~ aside."""
    for a in range(8):
        for i in range(3):
            fe[e, a, i] = 0.0
    for i in range(3):
        for j in range(3):
            B0[i, j] = 0.0  # symmetric factor of the dF0 term (before F0)
    for s in range(6):
        cs[s] = 0.0
    for q in range(8):
        i00, i01, i02, i10, i11, i12, i20, i21, i22 = _inv3_at(Fans, e, q)
        for j in range(3):  # S = F~^-1 P~ into T
            p0, p1, p2 = Pans[e, q, 0, j], Pans[e, q, 1, j], Pans[e, q, 2, j]
            T[0, j] = i00 * p0 + i01 * p1 + i02 * p2
            T[1, j] = i10 * p0 + i11 * p1 + i12 * p2
            T[2, j] = i20 * p0 + i21 * p1 + i22 * p2
        for i in range(3):
            for j in range(3):
                Sq[q, i, j] = 0.5 * (T[i, j] + T[j, i])
    _point_mean(Sq, w, e, Sbar)
    for q in range(8):
        wq = w[e, q]
        # the modification K_q - K_bar sees the stress's deviation from its element mean: T = (S - S_bar) Jinv^T
        for i in range(3):
            d0, d1, d2 = Sq[q, i, 0] - Sbar[i, 0], Sq[q, i, 1] - Sbar[i, 1], Sq[q, i, 2] - Sbar[i, 2]
            for j in range(3):
                T[i, j] = d0 * Jinv[e, q, j, 0] + d1 * Jinv[e, q, j, 1] + d2 * Jinv[e, q, j, 2]
        # w S~ = w Jinv T off its diagonal (the diagonal is not used)
        j00, j01, j02 = Jinv[e, q, 0, 0], Jinv[e, q, 0, 1], Jinv[e, q, 0, 2]
        j10, j11, j12 = Jinv[e, q, 1, 0], Jinv[e, q, 1, 1], Jinv[e, q, 1, 2]
        j20, j21, j22 = Jinv[e, q, 2, 0], Jinv[e, q, 2, 1], Jinv[e, q, 2, 2]
        s01 = wq * (j00 * T[0, 1] + j01 * T[1, 1] + j02 * T[2, 1])
        s02 = wq * (j00 * T[0, 2] + j01 * T[1, 2] + j02 * T[2, 2])
        s10 = wq * (j10 * T[0, 0] + j11 * T[1, 0] + j12 * T[2, 0])
        s12 = wq * (j10 * T[0, 2] + j11 * T[1, 2] + j12 * T[2, 2])
        s20 = wq * (j20 * T[0, 0] + j21 * T[1, 0] + j22 * T[2, 0])
        s21 = wq * (j20 * T[0, 1] + j21 * T[1, 1] + j22 * T[2, 1])
        cs[index[q, 0]] += s01
        cs[index[q, 1]] += s12
        cs[index[q, 2]] += s02
        # split w S~ into its diagonal (kept at q) and off-diagonal (moved to the affine part) in Cartesian form:
        # off_ij = sum_{k != m} G_ik S~_km G_jm, T = w S - off
        for i in range(3):
            gi0, gi1, gi2 = Gq[e, q, i, 0], Gq[e, q, i, 1], Gq[e, q, i, 2]
            p01, p02, p10, p12, p20, p21 = gi0 * s01, gi0 * s02, gi1 * s10, gi1 * s12, gi2 * s20, gi2 * s21
            for j in range(3):
                gj0, gj1, gj2 = Gq[e, q, j, 0], Gq[e, q, j, 1], Gq[e, q, j, 2]
                off = ((((0.0 + p01 * gj1) + p02 * gj2) + p10 * gj0) + p12 * gj2) + p20 * gj0 + p21 * gj1
                T[i, j] = wq * Sq[q, i, j] - off
                B0[i, j] += off
        # M = F T against the point's shape gradients
        f00, f01, f02 = F[e, q, 0, 0], F[e, q, 0, 1], F[e, q, 0, 2]
        f10, f11, f12 = F[e, q, 1, 0], F[e, q, 1, 1], F[e, q, 1, 2]
        f20, f21, f22 = F[e, q, 2, 0], F[e, q, 2, 1], F[e, q, 2, 2]
        t00, t01, t02, t10, t11, t12 = T[0, 0], T[0, 1], T[0, 2], T[1, 0], T[1, 1], T[1, 2]
        t20, t21, t22 = T[2, 0], T[2, 1], T[2, 2]
        m00 = f00 * t00 + f01 * t10 + f02 * t20
        m01 = f00 * t01 + f01 * t11 + f02 * t21
        m02 = f00 * t02 + f01 * t12 + f02 * t22
        m10 = f10 * t00 + f11 * t10 + f12 * t20
        m11 = f10 * t01 + f11 * t11 + f12 * t21
        m12 = f10 * t02 + f11 * t12 + f12 * t22
        m20 = f20 * t00 + f21 * t10 + f22 * t20
        m21 = f20 * t01 + f21 * t11 + f22 * t21
        m22 = f20 * t02 + f21 * t12 + f22 * t22
        for a in range(8):
            d0, d1, d2 = dN[e, q, a, 0], dN[e, q, a, 1], dN[e, q, a, 2]
            fe[e, a, 0] += m00 * d0 + m01 * d1 + m02 * d2
            fe[e, a, 1] += m10 * d0 + m11 * d1 + m12 * d2
            fe[e, a, 2] += m20 * d0 + m21 * d1 + m22 * d2
    for s in range(6):
        i, j = PAIRS[s // 2]
        c = cs[s]
        for r in range(3):
            for m in range(3):
                B0[r, m] -= c * (Gs[e, s, r, i] * Gs[e, s, m, j] + Gs[e, s, r, j] * Gs[e, s, m, i])
        for a in range(8):
            di, dj = c * dxi_s[s, a, i], c * dxi_s[s, a, j]
            for r in range(3):
                fe[e, a, r] += gs[e, s, r, 1] * di + gs[e, s, r, 0] * dj
    for i in range(3):
        f0, f1, f2 = F0s[e, i, 0], F0s[e, i, 1], F0s[e, i, 2]
        m0 = f0 * B0[0, 0] + f1 * B0[1, 0] + f2 * B0[2, 0]
        m1 = f0 * B0[0, 1] + f1 * B0[1, 1] + f2 * B0[2, 1]
        m2 = f0 * B0[0, 2] + f1 * B0[1, 2] + f2 * B0[2, 2]
        for a in range(8):
            fe[e, a, i] += m0 * b[e, a, 0] + m1 * b[e, a, 1] + m2 * b[e, a, 2]


class Hex8AnsGroup(Hex8Group):
    """Hexahedra of formulation ``ans`` (module docstring); everything but the kinematics and forces as ``Hex8Group``
    with 2x2x2 points. ``F`` is the true deformation gradient, ``F_material`` (n_el, 8, 3, 3) the one the material
    sees (output stresses and diagnostics use it)."""

    def __init__(self, name, formulation, X, conn, ids, material, params, frame, rho, hourglass=None):
        super().__init__(name, formulation, X, conn, ids, material, params, frame, rho, None)
        n_el = len(self.conn)
        self.ans = prepare_ans(X, self.conn)
        self.F_material = self.F.copy()
        self.F0, self.gs = np.zeros((n_el, 3, 3)), np.zeros((n_el, 6, 3, 2))

    def update(self, x, v):
        """Kinematics, material, element forces at positions x (n_node, 3); v unused (no hourglass control)."""
        a = self.ans
        kinematics_ans(x, self.conn, self.b, self.dN, self.w, a["dxi_s"], a["index"], a["Jinv"], a["Gq"], a["Gs"],
                       self.F, self.J, self.F_material, self.F0, self.gs)
        self.material.evaluate(self.F_material, self.frame, self.params, self.state, self.P, self.psi, self.modulus)
        forces_ans(self.F, self.F_material, self.P, self.dN, self.w, self.b, a["dxi_s"], a["index"], a["Jinv"],
                   a["Gq"], a["Gs"], self.F0, self.gs, self.fe)


def build(name, section, X, conn, ids, material, params, orientation, rho, cell_type):
    """Registry hook: a Hex8AnsGroup for one section card."""
    try:
        frames = orientation.frames()
    except ValueError as exc:
        raise CompileError([(("orientation",), str(exc))]) from None
    return Hex8AnsGroup(name, section.formulation, X, conn, ids, material, params, frames, rho, None)


register_formulation(FormulationKind("ans", build, 8))
