"""Eight-node hexahedra ``ans_tbar`` and ``ans_fbar``: the assumed natural shears of ``ans`` plus an element-averaged
measure, as F-bar averages the Jacobian.

Why. ``ans`` (``hex8_ans``) bends without shear locking, but on the thick interlock of [B] (MODELS §4, three-point
bending) the parasitic transverse shear it removes was also what held back the spurious transverse modes: on the
3 mm deck its indicator is 1.99 mm alone and 0.084 mm with fibre bending, against F-bar's 0.118 and 0.022 mm.
F-bar holds them back another way: F_bar = (J_bar / J)^(1/3) F passes a third of any element-scale volume change
into the fibre stretch, so a thickness that varies along the fibre inside an element (the u_z ~ xi zeta pattern
that dominates the `ans` run) meets the fibre stiffness. Both formulations here give the material

    F^ = r F',   r = (m_bar / m)^(1/3),

with F' the ``ans`` gradient F~ (F~^T F~ = C~, the assumed-shear right Cauchy-Green tensor; for ``ans_tbar`` with
its thickness stretch set to the true one, below), m a scalar measure at the point and m_bar its element mean:

* ``ans_fbar``: m = det F~ at the point, m_bar = (1/V0) sum_q w_q det F_q from the *true* F (m_bar V0 is the
  current element volume). F-bar on top of the assumed shears: it cures volumetric locking of isotropic laws too,
  but with a bimodular fabric it passes the element-scale volume change of the compressed, soft fibres into the
  stiff weft and compaction: cantilevers with 1 % fibre compression are 12-18 % too stiff on four layers
  (``test_bending_locking``).
* ``ans_tbar``: m = T = (f3 . C^-1 . f3)^(-1/2), the stretch normal to the deformed fibre plane from the *true* C
  (the exponential of fabric_hyper's compaction invariant; f3 the reference through-thickness direction, third row
  of the frame), m_bar = (1/V0) sum_q w_q T_q, and the material is given F~' in place of F~, the assumed-shear
  gradient with its thickness stretch set to the true one:

      F~' = F~ + (T - T~) T~ k~ (x) f3,   k~ = F~^-T f3,   C~' = F~'^T F~' = C~ + (T^2 - T~^2) f3 (x) f3,

  which keeps C~'s fibre stretches and its in-plane and transverse shear components f_i . C~ . f_j (fabric_hyper's
  transverse-shear invariants, normalised by f3 . C . f3, move with it) and sets f3 . C~'^-1 . f3 = 1 / T^2
  (rank-one update, Sherman-Morrison). Why: C~ keeps the true normal strain along f3 (C_33 = |F f3|^2 on a
  parallelepiped; the mean-free modification of ``hex8_ans`` adds to it on distorted elements) but drops the
  shear part of it, so T~ from C~ overstates the thickness wherever the true transverse shear exceeds the assumed
  one. In the keystone mode of a bent hexahedron (its thickness edges fanned out, top face shorter than the bottom)
  T~ stays near its rest value while the true thickness at two corners goes to zero: the tetrahedron's apex element
  on 5 mm crushed so (true T 0.02 and 0.00 at two points where T~ read 0.66, recomputed from the frame before
  the inversion), with no compaction energy to stop it. In pure bending (u_x = kappa x z) the true T is exactly 1
  while T~ = (1 + kappa^2 x^2)^(1/2), so the update also removes a second-order thickness stretch of bending.
  Only thickness changes are coupled into the fibre stretch, the fibre stretch's own gradient (bending) is left
  to the element: cantilevers as ``ans``, the three-point-bending indicator as F-bar's. Not a cure for volumetric
  locking (T is not the volume).

For every affine motion F~ = F and the point measures are uniform, so r = 1 (and F~' = F~): the patch stress and
the objectivity of ``ans`` are kept (r and T are invariants of C~ and C).

Forces, exact derivatives of W = sum_q w_q psi(F^_q). With S^ = F^-1 P^ (the law's second Piola-Kirchhoff stress
at F^) and p_q = (P^ : F^) / 3, as in F-bar (de Souza Neto, Peric, Dutko and Owen, Design of simple low order
finite elements for large strain analysis of nearly incompressible solids, 1996):

    dW = sum_q w_q [1/2 r^2 S^ : dC'_q - p_q d ln m_q] + (sum_q w_q p_q) d ln m_bar,

with C' = F'^T F' (C~ for ``ans_fbar``, C~' for ``ans_tbar``).
``ans_fbar``: m = det F~ at the point, d ln m = 1/2 C~^-1 : dC~, so the first part is ``hex8_ans.forces_ans``
fed with the stress P_eff = F~ (r^2 S^ - p C~^-1) = r P^ - p F~^-T (that kernel takes S = F~^-1 P_eff), and the
second part is F-bar's mean-dilatation force (pbar / J_bar) sum_q w_q cof F_q . dN_q, pbar the volume average of p.
``ans_tbar``: with s33 = f3 . S^ . f3, d(T~^2) = T~^4 (m~ (x) m~) : dC~ (m~ = C~^-1 f3) and d ln T = 1/2 T^2
(m (x) m) : dC (m = C^-1 f3, true C), dW splits into a part through dC~, the stress S_A = r^2 (S^ - s33 T~^4 m~ (x)
m~) given to ``forces_ans``, and a part through the true C, b_q d ln T_q with b = r^2 s33 T^2 - p + pbar T / T_bar
(``add_thickness_forces``: node a receives w_q b_q T_q^2 k_q (m_q . dN_qa), k = F^-T f3).

Stable step: the ``element_dt`` rule with F-bar's coupling 1/9; without it the estimate exceeds the exact critical
step of thin fabric meshes (exact / estimate 0.63-0.77, ``test_bending_locking``).
Units as in ``hex8``: x [mm], forces [N], stresses [MPa], volumes [mm^3].
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.jit import njit_parallel, prange
from fdeck.physics.elements.hex8 import _det_at, _inline, mean_pressure
from fdeck.physics.elements.hex8_ans import CHUNK, Hex8AnsGroup, _inv3_at, forces_ans, kinematics_ans
from fdeck.registry import FormulationKind, register_formulation

COUPLING = 1.0 / 9.0
"""Stable-step coupling of the volume averaging (as F-bar's, ``hex8.Hex8Group``)."""


@_inline
def _cof(F, e, q, i, j):
    """Cofactor (i, j) of F[e, q] (F (n_el, n_qp, 3, 3)): cof F = det F F^-T, indexed in place."""
    i1, i2 = (i + 1) % 3, (i + 2) % 3
    j1, j2 = (j + 1) % 3, (j + 2) % 3
    return F[e, q, i1, j1] * F[e, q, i2, j2] - F[e, q, i1, j2] * F[e, q, i2, j1]


@njit_parallel
def fbar_on_ans(w, J, Fans, Jans, Jbar, ratio, Fmat):
    """Fmat (n_el, 8, 3, 3) = ratio F~ with ratio (n_el, 8) = (Jbar / J~)^(1/3), J~ = det F~ into Jans (n_el, 8),
    Jbar (n_el,) = sum_q w_q J_q / V0 from the true Jacobians J (n_el, 8); w (n_el, 8) point volumes [mm^3].
    A non-positive J~ or Jbar gives nan (the engine's inversion monitor reports it)."""
    n_qp = w.shape[1]
    for e in prange(w.shape[0]):
        vol = 0.0
        jw = 0.0
        for q in range(n_qp):
            vol += w[e, q]
            jw += w[e, q] * J[e, q]
        Jbar[e] = jw / vol
        for q in range(n_qp):
            ja = _det_at(Fans, e, q)
            Jans[e, q] = ja
            r = (Jbar[e] / ja) ** (1.0 / 3.0) if ja > 0.0 and Jbar[e] > 0.0 else np.nan
            ratio[e, q] = r
            for i in range(3):
                for j in range(3):
                    Fmat[e, q, i, j] = r * Fans[e, q, i, j]


@njit_parallel
def stress_ans_fbar(Fans, Jans, ratio, Pmat, w, Peff, p, pbar):
    """Peff (n_el, 8, 3, 3) = r P^ - p F~^-T [MPa], the stress ``forces_ans`` turns into the C~ part of dW; p
    (n_el, 8) = r (P^ : F~) / 3 [MPa] and pbar (n_el,) its volume average, the J_bar part. Pmat = dpsi/dF^
    (n_el, 8, 3, 3) from the material at F^ = r F~."""
    n_qp = w.shape[1]
    for e in prange(w.shape[0]):
        pbar[e] = mean_pressure(Pmat, Fans, ratio, w, p, e)
        for q in range(n_qp):
            r = ratio[e, q]
            c = p[e, q] / Jans[e, q]  # p F~^-T = (p / J~) cof F~
            for i in range(3):
                for j in range(3):
                    Peff[e, q, i, j] = r * Pmat[e, q, i, j] - c * _cof(Fans, e, q, i, j)


@njit_parallel
def add_mean_dilatation(F, Jbar, pbar, dN, w, fe):
    """fe (n_el, 8, 3) += (pbar / Jbar) sum_q w_q cof(F_q) . dN_qa [N]: the derivative of (sum_q w_q p_q) ln Jbar
    with p held, Jbar = sum_q w_q det F_q / V0 from the true F (n_el, 8, 3, 3); dN (n_el, 8, 8, 3) [1/mm]."""
    n_qp = dN.shape[1]
    for e in prange(fe.shape[0]):
        s = pbar[e] / Jbar[e]
        for q in range(n_qp):
            c00, c01, c02 = _cof(F, e, q, 0, 0), _cof(F, e, q, 0, 1), _cof(F, e, q, 0, 2)
            c10, c11, c12 = _cof(F, e, q, 1, 0), _cof(F, e, q, 1, 1), _cof(F, e, q, 1, 2)
            c20, c21, c22 = _cof(F, e, q, 2, 0), _cof(F, e, q, 2, 1), _cof(F, e, q, 2, 2)
            k = s * w[e, q]
            for a in range(8):
                d0, d1, d2 = k * dN[e, q, a, 0], k * dN[e, q, a, 1], k * dN[e, q, a, 2]
                fe[e, a, 0] += c00 * d0 + c01 * d1 + c02 * d2
                fe[e, a, 1] += c10 * d0 + c11 * d1 + c12 * d2
                fe[e, a, 2] += c20 * d0 + c21 * d1 + c22 * d2


class Hex8AnsFbarGroup(Hex8AnsGroup):
    """Hexahedra of formulation ``ans_fbar`` (module docstring). ``F`` is the true deformation gradient, ``Fans``
    (n_el, 8, 3, 3) the assumed-shear one, ``F_material`` = ratio Fans the one the material sees (output stresses
    and diagnostics use it); ``Jbar`` (n_el,) the mean Jacobian."""

    def __init__(self, name, formulation, X, conn, ids, material, params, frame, rho, hourglass=None):
        super().__init__(name, formulation, X, conn, ids, material, params, frame, rho, None)
        n_el = len(self.conn)
        self.Fans = self.F.copy()
        self.Jans, self.ratio, self.p = np.ones((n_el, 8)), np.ones((n_el, 8)), np.zeros((n_el, 8))
        self.Jbar, self.pbar = np.ones(n_el), np.zeros(n_el)
        self.Peff = np.zeros_like(self.P)
        self.dt_coupling = COUPLING

    def update(self, x, v):
        """Kinematics, material, element forces at positions x (n_node, 3); v unused (no hourglass control)."""
        a = self.ans
        kinematics_ans(x, self.conn, self.b, self.dN, self.w, a["dxi_s"], a["index"], a["Jinv"], a["Gq"], a["Gs"],
                       self.F, self.J, self.Fans, self.F0, self.gs)
        fbar_on_ans(self.w, self.J, self.Fans, self.Jans, self.Jbar, self.ratio, self.F_material)
        self.material.evaluate(self.F_material, self.frame, self.params, self.state, self.P, self.psi, self.modulus)
        stress_ans_fbar(self.Fans, self.Jans, self.ratio, self.P, self.w, self.Peff, self.p, self.pbar)
        forces_ans(self.F, self.Fans, self.Peff, self.dN, self.w, self.b, a["dxi_s"], a["index"], a["Jinv"],
                   a["Gq"], a["Gs"], self.F0, self.gs, self.fe)
        add_mean_dilatation(self.F, self.Jbar, self.pbar, self.dN, self.w, self.fe)

    def cell_fields(self, idx=None, names=None) -> dict[str, np.ndarray]:
        """As ``Hex8Group.cell_fields`` (at F^), plus ``J_bar`` (n,) the elements' mean Jacobian."""
        out = super().cell_fields(idx, names)
        out["J_bar"] = self.Jbar[np.arange(len(self.conn)) if idx is None else np.asarray(idx)]
        return out


@_inline
def _thickness_direction(F, frame, e, q, d):
    """F^-1 (nine scalars, row by row), k = F^-T f3 (three) and |k|^2 = f3 . C^-1 . f3 = 1 / T^2 at point (e, q)
    of a gradient field F (n_el, n_qp, 3, 3), with d = det F (the caller's, computed once); T is the thickness
    stretch normal to the deformed fibre plane, f3 the third row of frame (n_el, 3, 3). Scalars, not scratch
    arrays, so that nothing is reloaded after the caller's stores (docs/kernels.md, item 13)."""
    r = 1.0 / d
    f00, f01, f02 = F[e, q, 0, 0], F[e, q, 0, 1], F[e, q, 0, 2]
    f10, f11, f12 = F[e, q, 1, 0], F[e, q, 1, 1], F[e, q, 1, 2]
    f20, f21, f22 = F[e, q, 2, 0], F[e, q, 2, 1], F[e, q, 2, 2]
    # (F^-1)_ji = cof(F)_ij / det F
    g00, g10, g20 = (f11 * f22 - f12 * f21) * r, (f12 * f20 - f10 * f22) * r, (f10 * f21 - f11 * f20) * r
    g01, g11, g21 = (f21 * f02 - f22 * f01) * r, (f22 * f00 - f20 * f02) * r, (f20 * f01 - f21 * f00) * r
    g02, g12, g22 = (f01 * f12 - f02 * f11) * r, (f02 * f10 - f00 * f12) * r, (f00 * f11 - f01 * f10) * r
    n0, n1, n2 = frame[e, 2, 0], frame[e, 2, 1], frame[e, 2, 2]
    k0 = g00 * n0 + g10 * n1 + g20 * n2
    k1 = g01 * n0 + g11 * n1 + g21 * n2
    k2 = g02 * n0 + g12 * n1 + g22 * n2
    return (g00, g01, g02, g10, g11, g12, g20, g21, g22, k0, k1, k2, ((0.0 + k0 * k0) + k1 * k1) + k2 * k2)


@_inline
def _thickness(F, frame, e, q):
    """T = (f3 . C^-1 . f3)^(-1/2) at point (e, q) of F (n_el, n_qp, 3, 3), nan when det F <= 0, followed by
    ``_thickness_direction``'s F^-1 (nine scalars) and k = F^-T f3 (three)."""
    d = _det_at(F, e, q)
    g00, g01, g02, g10, g11, g12, g20, g21, g22, k0, k1, k2, n2 = _thickness_direction(F, frame, e, q, d)
    t = 1.0 / math.sqrt(n2) if d > 0.0 else np.nan
    return t, g00, g01, g02, g10, g11, g12, g20, g21, g22, k0, k1, k2


@njit_parallel
def tbar_on_ans(w, F, Fans, frame, T, Tbar, ratio, Fmat):
    """Fmat (n_el, 8, 3, 3) = ratio F~', F~' = F~ + (T - T~) T~ k~ (x) f3 the assumed-shear gradient with its
    thickness stretch set to the true one (k~ = F~^-T f3; F~'^T F~' = C~ + (T^2 - T~^2) f3 (x) f3), ratio (n_el, 8)
    = (Tbar / T)^(1/3). T (n_el, 8) = (f3 . C^-1 . f3)^(-1/2) from the true F, the stretch normal to the deformed
    fibre plane (exp of fabric_hyper's compaction invariant), T~ the same of F~ (not kept), Tbar (n_el,) the volume
    average of T; frame (n_el, 3, 3) rows f1, f2, f3. A non-positive det F or det F~ gives nan."""
    n_el, n_qp = w.shape
    for chunk in prange((n_el + CHUNK - 1) // CHUNK):
        ck = np.empty((n_qp, 3))  # (T - T~) T~ k~ per point
        for e in range(chunk * CHUNK, min(n_el, (chunk + 1) * CHUNK)):
            vol = 0.0
            tw = 0.0
            for q in range(n_qp):
                t = _thickness(F, frame, e, q)[0]
                ta, _, _, _, _, _, _, _, _, _, k0, k1, k2 = _thickness(Fans, frame, e, q)
                T[e, q] = t
                vol += w[e, q]
                tw += w[e, q] * t
                c = (t - ta) * ta
                ck[q, 0], ck[q, 1], ck[q, 2] = c * k0, c * k1, c * k2
            Tbar[e] = tw / vol
            n0, n1, n2 = frame[e, 2, 0], frame[e, 2, 1], frame[e, 2, 2]
            for q in range(n_qp):
                r = (Tbar[e] / T[e, q]) ** (1.0 / 3.0)
                ratio[e, q] = r
                for i in range(3):
                    c = ck[q, i]
                    Fmat[e, q, i, 0] = (Fans[e, q, i, 0] + c * n0) * r
                    Fmat[e, q, i, 1] = (Fans[e, q, i, 1] + c * n1) * r
                    Fmat[e, q, i, 2] = (Fans[e, q, i, 2] + c * n2) * r


@njit_parallel
def stress_ans_tbar(Fans, frame, T, Tbar, ratio, Fmat, Pmat, w, p, Peff, b):
    """The two stresses of dW (module docstring): Peff (n_el, 8, 3, 3) = F~ S_A [MPa], S_A = r^2 (S^ - s33 T~^4
    m~ (x) m~), the part through dC~ (``forces_ans``), with S^ = F^^-1 P^ the law's second Piola-Kirchhoff stress,
    s33 = f3 . S^ . f3 and m~ = C~^-1 f3; b (n_el, 8) = r^2 s33 T^2 - p + pbar T / Tbar [MPa], the factor of
    d ln T through the true C (``add_thickness_forces``); p = (P^ : F^) / 3 (n_el, 8) [MPa], pbar its volume
    average. Pmat = dpsi/dF^ (n_el, 8, 3, 3) from the material at F^ = Fmat."""
    n_el, n_qp = w.shape
    for chunk in prange((n_el + CHUNK - 1) // CHUNK):
        S = np.empty((3, 3))
        for e in range(chunk * CHUNK, min(n_el, (chunk + 1) * CHUNK)):
            vol = 0.0
            pw = 0.0
            for q in range(n_qp):
                pf = 0.0
                for i in range(3):
                    for j in range(3):
                        pf += Pmat[e, q, i, j] * Fmat[e, q, i, j]
                p[e, q] = pf / 3.0
                pw += w[e, q] * p[e, q]
                vol += w[e, q]
            pbar = pw / vol
            n0, n1, n2 = frame[e, 2, 0], frame[e, 2, 1], frame[e, 2, 2]
            for q in range(n_qp):
                h00, h01, h02, h10, h11, h12, h20, h21, h22 = _inv3_at(Fmat, e, q)
                for j in range(3):
                    p0, p1, p2 = Pmat[e, q, 0, j], Pmat[e, q, 1, j], Pmat[e, q, 2, j]
                    S[0, j] = h00 * p0 + h01 * p1 + h02 * p2
                    S[1, j] = h10 * p0 + h11 * p1 + h12 * p2
                    S[2, j] = h20 * p0 + h21 * p1 + h22 * p2
                s33 = 0.0
                s33 += n0 * (S[0, 0] * n0 + S[0, 1] * n1 + S[0, 2] * n2)
                s33 += n1 * (S[1, 0] * n0 + S[1, 1] * n1 + S[1, 2] * n2)
                s33 += n2 * (S[2, 0] * n0 + S[2, 1] * n1 + S[2, 2] * n2)
                r2 = ratio[e, q] * ratio[e, q]
                t = T[e, q]
                b[e, q] = r2 * s33 * t * t - p[e, q] + pbar * t / Tbar[e]
                g00, g01, g02, g10, g11, g12, g20, g21, g22, k0, k1, k2, nk = _thickness_direction(
                    Fans, frame, e, q, _det_at(Fans, e, q))
                m0 = g00 * k0 + g01 * k1 + g02 * k2  # C~^-1 f3 = F~^-1 F~^-T f3
                m1 = g10 * k0 + g11 * k1 + g12 * k2
                m2 = g20 * k0 + g21 * k1 + g22 * k2
                c = r2 * s33 / (nk * nk)  # r^2 s33 T~^4; F~ m~ = k~
                for i in range(3):
                    a0, a1, a2 = Fans[e, q, i, 0], Fans[e, q, i, 1], Fans[e, q, i, 2]
                    ci = c * (k0 if i == 0 else k1 if i == 1 else k2)
                    Peff[e, q, i, 0] = r2 * (a0 * S[0, 0] + a1 * S[1, 0] + a2 * S[2, 0]) - ci * m0
                    Peff[e, q, i, 1] = r2 * (a0 * S[0, 1] + a1 * S[1, 1] + a2 * S[2, 1]) - ci * m1
                    Peff[e, q, i, 2] = r2 * (a0 * S[0, 2] + a1 * S[1, 2] + a2 * S[2, 2]) - ci * m2


@njit_parallel
def add_thickness_forces(F, frame, T, b, dN, w, fe):
    """fe (n_el, 8, 3) += sum_q w_q b_q d ln T_q / dx [N]: d ln T = 1/2 T^2 (m (x) m) : dC with m = C^-1 f3, so the
    force on node a is w_q b_q T_q^2 k_q (m_q . dN_qa), k = F^-T f3 = F m; F (n_el, 8, 3, 3) the true gradient, b
    (n_el, 8) [MPa] from ``stress_ans_tbar``, dN (n_el, 8, 8, 3) [1/mm], w (n_el, 8) [mm^3]."""
    n_el, n_qp = w.shape
    for e in prange(n_el):
        for q in range(n_qp):
            _, g00, g01, g02, g10, g11, g12, g20, g21, g22, k0, k1, k2 = _thickness(F, frame, e, q)
            m0 = g00 * k0 + g01 * k1 + g02 * k2
            m1 = g10 * k0 + g11 * k1 + g12 * k2
            m2 = g20 * k0 + g21 * k1 + g22 * k2
            c = w[e, q] * b[e, q] * T[e, q] * T[e, q]
            for a in range(8):
                d = c * (m0 * dN[e, q, a, 0] + m1 * dN[e, q, a, 1] + m2 * dN[e, q, a, 2])
                fe[e, a, 0] += d * k0
                fe[e, a, 1] += d * k1
                fe[e, a, 2] += d * k2


class Hex8AnsTbarGroup(Hex8AnsGroup):
    """Hexahedra of formulation ``ans_tbar``: the assumed-shear gradient with its thickness stretch set to the true
    one, and the element mean of that stretch T = (f3 . C^-1 . f3)^(-1/2) in place of ``ans_fbar``'s mean Jacobian
    (module docstring). ``Fans`` the assumed-shear gradient, ``F_material`` the one the material sees, ``T``
    (n_el, 8) the thickness stretch of the true F, ``Tbar`` (n_el,) its element mean."""

    def __init__(self, name, formulation, X, conn, ids, material, params, frame, rho, hourglass=None):
        super().__init__(name, formulation, X, conn, ids, material, params, frame, rho, None)
        n_el = len(self.conn)
        self.Fans = self.F.copy()
        self.T, self.ratio = np.ones((n_el, 8)), np.ones((n_el, 8))
        self.p, self.bT = np.zeros((n_el, 8)), np.zeros((n_el, 8))
        self.Tbar = np.ones(n_el)
        self.Peff = np.zeros_like(self.P)
        self.dt_coupling = COUPLING

    def update(self, x, v):
        """Kinematics, material, element forces at positions x (n_node, 3); v unused (no hourglass control)."""
        a = self.ans
        kinematics_ans(x, self.conn, self.b, self.dN, self.w, a["dxi_s"], a["index"], a["Jinv"], a["Gq"], a["Gs"],
                       self.F, self.J, self.Fans, self.F0, self.gs)
        tbar_on_ans(self.w, self.F, self.Fans, self.frame, self.T, self.Tbar, self.ratio, self.F_material)
        self.material.evaluate(self.F_material, self.frame, self.params, self.state, self.P, self.psi, self.modulus)
        stress_ans_tbar(self.Fans, self.frame, self.T, self.Tbar, self.ratio, self.F_material, self.P, self.w,
                        self.p, self.Peff, self.bT)
        forces_ans(self.F, self.Fans, self.Peff, self.dN, self.w, self.b, a["dxi_s"], a["index"], a["Jinv"],
                   a["Gq"], a["Gs"], self.F0, self.gs, self.fe)
        add_thickness_forces(self.F, self.frame, self.T, self.bT, self.dN, self.w, self.fe)


GROUPS = {"ans_fbar": Hex8AnsFbarGroup, "ans_tbar": Hex8AnsTbarGroup}


def build(name, section, X, conn, ids, material, params, orientation, rho, cell_type):
    """Registry hook: the group of ``section.formulation`` (``GROUPS``) for one section card."""
    try:
        frames = orientation.frames()
    except ValueError as exc:
        raise CompileError([(("orientation",), str(exc))]) from None
    return GROUPS[section.formulation](name, section.formulation, X, conn, ids, material, params, frames, rho, None)


for _name in GROUPS:
    register_formulation(FormulationKind(_name, build, 8))
