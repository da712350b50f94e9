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
bend as before. Every term is a dot product of current vectors, so C~ is objective. The material sees F~ = F Rc^-1 R~, Rc and R~ the upper Cholesky factors of
C = F^T F and C~ (F~^T F~ = C~, F~ = F when C~ = C, F~ -> Q F~ when F -> Q F), so any law of F (fabric_hyper,
linear_elastic, neo_hookean) serves unchanged; W = sum_q w_q psi(C~_q) and the forces are its exact derivative
(``forces_ans``): dW = sum_q w_q (F S : dF + S~_ij dDelta_ij) with S = F~^-1 P~ and
S~ = J0^-1 (S - S_bar) J0^-T, S_bar the element's volume mean of S (the mean-free modification's share).

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
from fdeck.physics.elements.hex8 import GAUSS_2, Hex8Group, _deformation_gradients, _det_at, shape_gradients_local
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


CHUNK = 32
"""Elements per scratch set: the kernels allocate their 3x3 scratch once per CHUNK elements, not per element (13
allocations per element cost a tenth of the kinematics: 0.93 -> 0.82 us per element, ``benchmarks/kernel_parts.py
ans_tbar fabric_hyper_3weave``, bitwise the same)."""


@njit_inline
def _chol_upper(C, R, Rinv):
    """R (3, 3) upper triangular with R^T R = C (3, 3) symmetric, Rinv (3,) the reciprocals of its diagonal (one
    division each, then multiplications); nan when C is not positive definite."""
    r00 = math.sqrt(C[0, 0])
    Rinv[0] = 1.0 / r00
    r01 = C[0, 1] * Rinv[0]
    r02 = C[0, 2] * Rinv[0]
    r11 = math.sqrt(C[1, 1] - r01 * r01)
    Rinv[1] = 1.0 / r11
    r12 = (C[1, 2] - r01 * r02) * Rinv[1]
    r22 = math.sqrt(C[2, 2] - r02 * r02 - r12 * r12)
    Rinv[2] = 1.0 / r22
    R[0, 0], R[0, 1], R[0, 2] = r00, r01, r02
    R[1, 0], R[1, 1], R[1, 2] = 0.0, r11, r12
    R[2, 0], R[2, 1], R[2, 2] = 0.0, 0.0, r22


@njit_inline
def _natural(A, G, e, s, i, j):
    """G[e, s][:, i] . A . G[e, s][:, j] for a (3, 3) A and base-vector columns G (n_el, n_s, 3, 3), in place."""
    acc = 0.0
    for k in range(3):
        acc += G[e, s, k, i] * (A[k, 0] * G[e, s, 0, j] + A[k, 1] * G[e, s, 1, j] + A[k, 2] * G[e, s, 2, j])
    return acc


@njit_inline
def _inv_at(A, e, q, out):
    """out (3, 3) = A[e, q]^-1 (A (n_el, n_qp, 3, 3)), indexed in place (the arithmetic of ``tensor.inv3``)."""
    r = 1.0 / _det_at(A, e, q)
    out[0, 0] = (A[e, q, 1, 1] * A[e, q, 2, 2] - A[e, q, 1, 2] * A[e, q, 2, 1]) * r
    out[0, 1] = (A[e, q, 0, 2] * A[e, q, 2, 1] - A[e, q, 0, 1] * A[e, q, 2, 2]) * r
    out[0, 2] = (A[e, q, 0, 1] * A[e, q, 1, 2] - A[e, q, 0, 2] * A[e, q, 1, 1]) * r
    out[1, 0] = (A[e, q, 1, 2] * A[e, q, 2, 0] - A[e, q, 1, 0] * A[e, q, 2, 2]) * r
    out[1, 1] = (A[e, q, 0, 0] * A[e, q, 2, 2] - A[e, q, 0, 2] * A[e, q, 2, 0]) * r
    out[1, 2] = (A[e, q, 0, 2] * A[e, q, 1, 0] - A[e, q, 0, 0] * A[e, q, 1, 2]) * r
    out[2, 0] = (A[e, q, 1, 0] * A[e, q, 2, 1] - A[e, q, 1, 1] * A[e, q, 2, 0]) * r
    out[2, 1] = (A[e, q, 0, 1] * A[e, q, 2, 0] - A[e, q, 0, 0] * A[e, q, 2, 1]) * r
    out[2, 2] = (A[e, q, 0, 0] * A[e, q, 1, 1] - A[e, q, 0, 1] * A[e, q, 1, 0]) * r


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
        C0 = np.empty((3, 3))
        Cq = np.empty((8, 3, 3))
        Kq = np.empty((8, 3, 3))
        Kbar = np.empty((3, 3))
        C = np.empty((3, 3))
        W = np.empty((3, 3))
        D = np.zeros((3, 3))  # natural shear correction Delta, zero diagonal (never written)
        T = np.empty((3, 3))
        Rc = np.empty((3, 3))
        Ra = np.empty((3, 3))
        M = np.empty((3, 3))
        A = np.empty(6)
        Rinv = np.empty(3)
        for e in range(chunk * CHUNK, min(n_el, (chunk + 1) * CHUNK)):
            _kinematics_element(x, conn, b, dN, w, dxi_s, index, Jinv, Gq, Gs, F, J, Fans, F0s, gs, e,
                                C0, Cq, Kq, Kbar, C, W, D, T, Rc, Ra, M, A, Rinv)


@njit_inline
def _kinematics_element(x, conn, b, dN, w, dxi_s, index, Jinv, Gq, Gs, F, J, Fans, F0s, gs, e,
                        C0, Cq, Kq, Kbar, C, W, D, T, Rc, Ra, M, A, Rinv):
    """``kinematics_ans`` for element e, with the chunk's scratch arrays (3, 3) but Cq, Kq (8, 3, 3), A (6,) and
    Rinv (3,)."""
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for a in range(8):
                acc += x[conn[e, a], i] * b[e, a, j]
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
                    acc += x[conn[e, a], r] * dxi_s[s, a, k]
                gs[e, s, r, c] = acc
        A[s] = (gs[e, s, 0, 0] * gs[e, s, 0, 1] + gs[e, s, 1, 0] * gs[e, s, 1, 1] + gs[e, s, 2, 0] * gs[e, s, 2, 1]
                - _natural(C0, Gs, e, s, i, j))
    _deformation_gradients(x, conn, dN, F, J, e)
    for q in range(8):
        for i in range(3):
            for j in range(3):
                C[i, j] = F[e, q, 0, i] * F[e, q, 0, j] + F[e, q, 1, i] * F[e, q, 1, j] + F[e, q, 2, i] * F[e, q, 2, j]
                Cq[q, i, j] = C[i, j]
                W[i, j] = C[i, j] - C0[i, j]
        for k in range(3):
            i, j = PAIRS[k]
            d = A[index[q, k]] - _natural(W, Gq, e, q, i, j)
            D[i, j] = d
            D[j, i] = d
        # K_q = Jinv^T D Jinv (T = D Jinv first)
        for i in range(3):
            for j in range(3):
                T[i, j] = D[i, 0] * Jinv[e, q, 0, j] + D[i, 1] * Jinv[e, q, 1, j] + D[i, 2] * Jinv[e, q, 2, j]
        for i in range(3):
            for j in range(3):
                Kq[q, i, j] = Jinv[e, q, 0, i] * T[0, j] + Jinv[e, q, 1, i] * T[1, j] + Jinv[e, q, 2, i] * T[2, j]
    _point_mean(Kq, w, e, Kbar)
    for q in range(8):
        for i in range(3):
            for j in range(3):
                C[i, j] = Cq[q, i, j]
        # C~ = C + K_q - K_bar (Ra's reciprocals first, then Rc's, kept for the back substitution)
        for i in range(3):
            for j in range(3):
                W[i, j] = C[i, j] + (Kq[q, i, j] - Kbar[i, j])
        _chol_upper(W, Ra, Rinv)
        _chol_upper(C, Rc, Rinv)
        # F~ = F Rc^-1 Ra: back substitution Rc M = Ra, then F M
        for j in range(3):
            for i in range(2, -1, -1):
                acc = Ra[i, j]
                for k in range(i + 1, 3):
                    acc -= Rc[i, k] * M[k, j]
                M[i, j] = acc * Rinv[i]
        for i in range(3):
            for j in range(3):
                Fans[e, q, i, j] = F[e, q, i, 0] * M[0, j] + F[e, q, i, 1] * M[1, j] + F[e, q, i, 2] * M[2, j]


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
        Fi = np.empty((3, 3))
        S = np.empty((3, 3))
        Sn = np.empty((3, 3))
        T = np.empty((3, 3))
        M = np.empty((3, 3))
        B0 = np.empty((3, 3))
        cs = np.empty(6)
        Sq = np.empty((8, 3, 3))
        Sbar = np.empty((3, 3))
        for e in range(chunk * CHUNK, min(n_el, (chunk + 1) * CHUNK)):
            _forces_element(F, Fans, Pans, dN, w, b, dxi_s, index, Jinv, Gq, Gs, F0s, gs, fe, e,
                            Fi, S, Sn, T, M, B0, cs, Sq, Sbar)


@njit_inline
def _forces_element(F, Fans, Pans, dN, w, b, dxi_s, index, Jinv, Gq, Gs, F0s, gs, fe, e,
                    Fi, S, Sn, T, M, B0, cs, Sq, Sbar):
    """``forces_ans`` for element e, with the chunk's scratch: (3, 3) arrays but cs (6,) and Sq (8, 3, 3)."""
    for a in range(8):
        for i in range(3):
            fe[e, a, i] = 0.0
    for i in range(3):
        for j in range(3):
            B0[i, j] = 0.0  # symmetric factor of the dF0 term (before F0)
    for s in range(6):
        cs[s] = 0.0
    for q in range(8):
        _inv_at(Fans, e, q, Fi)
        for i in range(3):
            for j in range(3):
                S[i, j] = Fi[i, 0] * Pans[e, q, 0, j] + Fi[i, 1] * Pans[e, q, 1, j] + Fi[i, 2] * Pans[e, q, 2, j]
        for i in range(3):
            for j in range(3):
                Sq[q, i, j] = 0.5 * (S[i, j] + S[j, i])
    _point_mean(Sq, w, e, Sbar)
    for q in range(8):
        # the modification K_q - K_bar sees the stress's deviation from its element mean, S - S_bar
        for i in range(3):
            for j in range(3):
                T[i, j] = ((Sq[q, i, 0] - Sbar[i, 0]) * Jinv[e, q, j, 0] + (Sq[q, i, 1] - Sbar[i, 1]) * Jinv[e, q, j, 1]
                           + (Sq[q, i, 2] - Sbar[i, 2]) * Jinv[e, q, j, 2])  # (S - S_bar) Jinv^T
        for i in range(3):
            for j in range(3):
                Sn[i, j] = w[e, q] * (Jinv[e, q, i, 0] * T[0, j] + Jinv[e, q, i, 1] * T[1, j]
                                      + Jinv[e, q, i, 2] * T[2, j])
        for k in range(3):
            i, j = PAIRS[k]
            cs[index[q, k]] += Sn[i, j]
        # split w S~ into its diagonal (kept at q) and off-diagonal (moved to the affine part) in Cartesian form
        for i in range(3):
            for j in range(3):
                off = 0.0
                for k in range(3):
                    for m in range(3):
                        if m != k:
                            off += Gq[e, q, i, k] * Sn[k, m] * Gq[e, q, j, m]
                T[i, j] = w[e, q] * Sq[q, i, j] - off
                B0[i, j] += off
        for i in range(3):
            for j in range(3):
                M[i, j] = F[e, q, i, 0] * T[0, j] + F[e, q, i, 1] * T[1, j] + F[e, q, i, 2] * T[2, j]
        for a in range(8):
            for i in range(3):
                fe[e, a, i] += M[i, 0] * dN[e, q, a, 0] + M[i, 1] * dN[e, q, a, 1] + M[i, 2] * dN[e, q, a, 2]
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
        for j in range(3):
            M[i, j] = F0s[e, i, 0] * B0[0, j] + F0s[e, i, 1] * B0[1, j] + F0s[e, i, 2] * B0[2, j]
    for a in range(8):
        for i in range(3):
            fe[e, a, i] += M[i, 0] * b[e, a, 0] + M[i, 1] * b[e, a, 1] + M[i, 2] * b[e, a, 2]


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
