"""fabric_hyper's point law over blocks of ``LANES`` points with the lanes innermost, so that LLVM packs it
(AVX2/AVX-512).

``fabric_hyper.point`` takes one point at a time: about 300 scalar flops, three ``log``, a ``pow`` and a dozen
divisions and square roots, 100-110 ns per point on this machine, 70 % of an F-bar 3WEAVE cycle (docs/kernels.md,
item 9). Here the same law runs on a block of points at once, stage by stage over rows of one work array
(n_rows, LANES): the kinematics, the stress and the step moduli are lane loops of plain arithmetic (square roots
and divisions included, which pack as ``vsqrtpd``/``vdivpd``); the logarithms and powers, which LLVM cannot pack
without a vector maths library, are scalar loops of their own; each energy form is chosen once per block (the form
ids are one row for the whole section), not per point. Every value is formed by the same operations in the same
order as ``fabric_hyper.point`` (the modulus by the same inlined ``_modulus``), so the two give the same bits
(``tests/test_fabric_hyper_blocks.py``) and a deck's results do not depend on which path ran. One exception, at
degenerate points only: where both paths give NaN (an inverted or flattened element, an infinite stretch), the NaN's
sign bit may differ (a positive ``math.nan`` meeting a negative NaN of 0 * inf in ``_modulus``, whose operands
LLVM may order differently in packed and scalar code); the engine stops a run at such a point. With Intel's SVML
present (``numba.config.USING_SVML``), LLVM would pack the log/pow loops with its vector maths, whose last bits are
not libm's: the block path is then not taken.

Shapes: F and P (n_el, n_qp, 3, 3), frame (n_el, 3, 3), prm (PARAMS.size,) the section's one parameter row, psi
(n_el, n_qp) [MPa], modulus (n_el, n_qp, 3) [MPa]; the points are taken in (element, point) order, the last block
padded by repeating the last point (its results are not written).
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.jit import njit_inline, njit_parallel, prange
from fdeck.physics.materials import blocks
from fdeck.physics.materials.fabric_hyper import BLOCK, PARAMS, _modulus, _poly, _tabulated

LANES = blocks.LANES

# rows of the work array: F[i, j] and frame[i, j] at 3 i + j; a_i[k] at A + 3 i + k; g = (g11, g22, g33, g12, g13,
# g23); q = 1/|a_i|; the six invariants (e1, e2, c, s, t1, t2); per mode psi_k, psi_k', psi_k''; P[i, j] at 3 i + j;
# the point's energy and three moduli; X, U two scratch rows (a form's argument, a power). 39 KB per block.
F_ROW, FR_ROW, A_ROW, G_ROW, Q_ROW, J_ROW, ID_ROW, I_ROW = 0, 9, 18, 27, 33, 36, 37, 38
PSI_ROW, D_ROW, H_ROW, P_ROW, OUT_ROW, X_ROW, U_ROW = 44, 50, 56, 62, 71, 75, 76
ROWS = 77


def evaluate(F, frame, params, state, P, psi, modulus) -> bool:
    """The block path where ``blocks.run`` allows it (a section's broadcast parameter row, contiguous arrays, no
    SVML); returns False (nothing done) otherwise, for the caller to take the point path."""
    return blocks.run(evaluate_blocks, F, frame, params, P, psi, modulus)


@njit_parallel
def evaluate_blocks(F, frame, n_qp, prm, P, psi, modulus):
    """F, P (n_pt, 3, 3), frame (n_pt // n_qp, 3, 3), psi (n_pt,), modulus (n_pt, 3): the module's stages per
    block."""
    n = F.shape[0]
    for blk in prange((n + LANES - 1) // LANES):
        w = np.empty((ROWS, LANES))
        blocks.gather(w, F, frame, n_qp, blk, F_ROW, FR_ROW)
        law_stages(w, prm)
        blocks.scatter(w, P, psi, modulus, blk, P_ROW, OUT_ROW)


@njit_inline
def law_stages(w, prm):
    """The law on one block's work rows w: F and the frame in rows F_ROW and FR_ROW in, P, psi and the three
    moduli in rows P_ROW and OUT_ROW out (also called by ``benchmarks/fused8_probe.py``). Inlined here: compiled as
    a function of its own with w passed in, it compiled in about 25 instead of 45-57 s but LLVM packed about half
    as much and the law ran at half the speed (docs/kernels.md, item 12)."""
    _kinematics(w)
    _invariants(w)
    _stretch(w, prm, 0)
    _stretch(w, prm, 1)
    for l in range(LANES):
        w[X_ROW, l] = w[I_ROW + 2, l]
    _form(w, prm, PARAMS.compaction, 2)
    _even(w, prm, 3)
    _even(w, prm, 4)
    _even(w, prm, 5)
    _stress(w)
    _moduli(w)


@njit_inline
def _kinematics(w):
    """``fabric_hyper._kinematics`` per lane: a_i = F f_i, g_ij = a_i . a_j, q_i = 1/|a_i|, J = det F,
    iD = 1/(g11 g22 - g12^2)."""
    for l in range(LANES):
        f00, f01, f02 = w[F_ROW, l], w[F_ROW + 1, l], w[F_ROW + 2, l]
        f10, f11, f12 = w[F_ROW + 3, l], w[F_ROW + 4, l], w[F_ROW + 5, l]
        f20, f21, f22 = w[F_ROW + 6, l], w[F_ROW + 7, l], w[F_ROW + 8, l]
        for i in range(3):  # push(F, frame, i)
            r0, r1, r2 = w[FR_ROW + 3 * i, l], w[FR_ROW + 3 * i + 1, l], w[FR_ROW + 3 * i + 2, l]
            w[A_ROW + 3 * i, l] = f00 * r0 + f01 * r1 + f02 * r2
            w[A_ROW + 3 * i + 1, l] = f10 * r0 + f11 * r1 + f12 * r2
            w[A_ROW + 3 * i + 2, l] = f20 * r0 + f21 * r1 + f22 * r2
        a10, a11, a12 = w[A_ROW, l], w[A_ROW + 1, l], w[A_ROW + 2, l]
        a20, a21, a22 = w[A_ROW + 3, l], w[A_ROW + 4, l], w[A_ROW + 5, l]
        a30, a31, a32 = w[A_ROW + 6, l], w[A_ROW + 7, l], w[A_ROW + 8, l]
        g11 = a10 * a10 + a11 * a11 + a12 * a12
        g22 = a20 * a20 + a21 * a21 + a22 * a22
        g33 = a30 * a30 + a31 * a31 + a32 * a32
        g12 = a10 * a20 + a11 * a21 + a12 * a22
        g13 = a10 * a30 + a11 * a31 + a12 * a32
        g23 = a20 * a30 + a21 * a31 + a22 * a32
        w[G_ROW, l], w[G_ROW + 1, l], w[G_ROW + 2, l] = g11, g22, g33
        w[G_ROW + 3, l], w[G_ROW + 4, l], w[G_ROW + 5, l] = g12, g13, g23
        w[Q_ROW, l] = 1.0 / math.sqrt(g11)
        w[Q_ROW + 1, l] = 1.0 / math.sqrt(g22)
        w[Q_ROW + 2, l] = 1.0 / math.sqrt(g33)
        w[J_ROW, l] = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
                       + f02 * (f10 * f21 - f11 * f20))
        w[ID_ROW, l] = 1.0 / (g11 * g22 - g12 * g12)


@njit_inline
def _invariants(w):
    """``fabric_hyper._invariants``: the three logarithms in a scalar loop (libm), the three sines packed."""
    for l in range(LANES):
        J = w[J_ROW, l]
        w[I_ROW, l] = 0.5 * math.log(w[G_ROW, l])
        w[I_ROW + 1, l] = 0.5 * math.log(w[G_ROW + 1, l])
        w[I_ROW + 2, l] = 0.5 * math.log(J * J * w[ID_ROW, l]) if J > 0.0 else math.nan
    for l in range(LANES):
        q1, q2, q3 = w[Q_ROW, l], w[Q_ROW + 1, l], w[Q_ROW + 2, l]
        w[I_ROW + 3, l] = w[G_ROW + 3, l] * q1 * q2
        w[I_ROW + 4, l] = w[G_ROW + 4, l] * q1 * q3
        w[I_ROW + 5, l] = w[G_ROW + 5, l] * q2 * q3


@njit_inline
def _stretch(w, prm, k):
    """``fabric_hyper._stretch`` for mode k (0 warp, 1 weft): the tensile form on every lane, then the compressive
    quadratic where the strain is negative (the tensile value computed there is discarded)."""
    for l in range(LANES):
        w[X_ROW, l] = w[I_ROW + k, l]
    _form(w, prm, k * BLOCK, k)
    kc = prm[PARAMS.compressive_k + k]
    for l in range(LANES):
        x = w[X_ROW, l]
        if x < 0.0:
            w[PSI_ROW + k, l] = kc * x * x
            w[D_ROW + k, l] = 2.0 * kc * x
            w[H_ROW + k, l] = 2.0 * kc


@njit_inline
def _even(w, prm, k):
    """``fabric_hyper._even`` for shear mode k: the form at |x|, the derivative's sign from x."""
    for l in range(LANES):
        w[X_ROW, l] = abs(w[I_ROW + k, l])
    _form(w, prm, k * BLOCK, k)
    for l in range(LANES):
        x = w[I_ROW + k, l]
        if x < 0.0:
            w[D_ROW + k, l] = -w[D_ROW + k, l]
        elif x == 0.0:
            w[D_ROW + k, l] = 0.0


@njit_inline
def _form(w, prm, o, k):
    """``fabric_hyper._form`` of the form packed at prm[o:o + BLOCK] at the arguments in row X_ROW, into mode k's
    rows; the form is chosen once for the block."""
    fid = int(prm[o])
    if fid == 1:
        for l in range(LANES):
            w[PSI_ROW + k, l], w[D_ROW + k, l], w[H_ROW + k, l] = _poly(prm, o + 1, w[X_ROW, l])
    elif fid == 2:
        x0 = prm[o + 1]
        for l in range(LANES):
            x = w[X_ROW, l]
            if x <= x0:
                w[PSI_ROW + k, l], w[D_ROW + k, l], w[H_ROW + k, l] = _poly(prm, o + 2, x)
            else:
                w[PSI_ROW + k, l], w[D_ROW + k, l], w[H_ROW + k, l] = _poly(prm, o + 7, x)
    elif fid == 3:
        _locking(w, prm, o + 1, k)
    elif fid == 4:
        _compaction(w, prm, o + 1, k)
    elif fid == 5:
        c = prm[o + 1]
        for l in range(LANES):
            x = w[X_ROW, l]
            w[PSI_ROW + k, l], w[D_ROW + k, l], w[H_ROW + k, l] = c * x * x, 2.0 * c * x, 2.0 * c
    elif fid == 6:  # a table walk per point: scalar
        for l in range(LANES):
            w[PSI_ROW + k, l], w[D_ROW + k, l], w[H_ROW + k, l] = _tabulated(prm, o + 1, w[X_ROW, l])
    else:
        for l in range(LANES):
            w[PSI_ROW + k, l], w[D_ROW + k, l], w[H_ROW + k, l] = 0.0, 0.0, 0.0


@njit_inline
def _locking(w, prm, o, k):
    """``fabric_hyper._locking``: the power (1 - x)^-p22 where x is past the cubic branch, scalar; the rest
    packed."""
    x0, k12, k13, p22, k21, psi20 = prm[o], prm[o + 1], prm[o + 2], prm[o + 3], prm[o + 4], prm[o + 5]
    for l in range(LANES):
        x = w[X_ROW, l]
        w[U_ROW, l] = 0.0 if x <= x0 else (1.0 - x) ** (-p22)
    for l in range(LANES):
        x = w[X_ROW, l]
        if x <= x0:
            w[PSI_ROW + k, l] = x * x * (k12 + k13 * x)
            w[D_ROW + k, l] = x * (2.0 * k12 + 3.0 * k13 * x)
            w[H_ROW + k, l] = 2.0 * k12 + 6.0 * k13 * x
        else:
            u = 1.0 - x
            up = w[U_ROW, l]
            d1 = k21 * p22 * up / u
            w[PSI_ROW + k, l] = k21 * up + psi20
            w[D_ROW + k, l] = d1
            w[H_ROW + k, l] = d1 * (p22 + 1.0) / u


@njit_inline
def _compaction(w, prm, o, k):
    """``fabric_hyper._compaction``: the power (1 - x/I0)^-p scalar, the rest packed."""
    c, r, e, d, h = prm[o], prm[o + 1], prm[o + 2], prm[o + 3], prm[o + 4]
    for l in range(LANES):
        w[U_ROW, l] = (1.0 - w[X_ROW, l] * r) ** (-e)
    for l in range(LANES):
        x = w[X_ROW, l]
        u = 1.0 - x * r
        up = w[U_ROW, l]
        w[PSI_ROW + k, l] = c * (up - e * x * r - 1.0)
        w[D_ROW + k, l] = d * (up / u - 1.0)
        w[H_ROW + k, l] = h * up / (u * u)


@njit_inline
def _stress(w):
    """P = sum_j B_j x f_j + dc cof(F) / J and psi = sum_k psi_k, as ``fabric_hyper.point``."""
    for l in range(LANES):
        g11, g22, g12 = w[G_ROW, l], w[G_ROW + 1, l], w[G_ROW + 3, l]
        q0, q1, q2 = w[Q_ROW, l], w[Q_ROW + 1, l], w[Q_ROW + 2, l]
        iD, J = w[ID_ROW, l], w[J_ROW, l]
        s, t1, t2 = w[I_ROW + 3, l], w[I_ROW + 4, l], w[I_ROW + 5, l]
        i11, i22, i33 = q0 * q0, q1 * q1, q2 * q2
        dw, df, dc = w[D_ROW, l], w[D_ROW + 1, l], w[D_ROW + 2, l]
        ds, d1, d2 = w[D_ROW + 3, l], w[D_ROW + 4, l], w[D_ROW + 5, l]
        w11 = dw * i11 - dc * g22 * iD - (ds * s + d1 * t1) * i11
        w22 = df * i22 - dc * g11 * iD - (ds * s + d2 * t2) * i22
        w33 = -(d1 * t1 + d2 * t2) * i33
        w12 = dc * g12 * iD + ds * q0 * q1
        w13 = d1 * q0 * q2
        w23 = d2 * q1 * q2
        gc = dc / J
        f00, f01, f02 = w[F_ROW, l], w[F_ROW + 1, l], w[F_ROW + 2, l]
        f10, f11, f12 = w[F_ROW + 3, l], w[F_ROW + 4, l], w[F_ROW + 5, l]
        f20, f21, f22 = w[F_ROW + 6, l], w[F_ROW + 7, l], w[F_ROW + 8, l]
        cof = ((f11 * f22 - f12 * f21, f12 * f20 - f10 * f22, f10 * f21 - f11 * f20),
               (f02 * f21 - f01 * f22, f00 * f22 - f02 * f20, f01 * f20 - f00 * f21),
               (f01 * f12 - f02 * f11, f02 * f10 - f00 * f12, f00 * f11 - f01 * f10))
        for r in range(3):
            ar1, ar2, ar3 = w[A_ROW + r, l], w[A_ROW + 3 + r, l], w[A_ROW + 6 + r, l]
            b1 = w11 * ar1 + w12 * ar2 + w13 * ar3
            b2 = w12 * ar1 + w22 * ar2 + w23 * ar3
            b3 = w13 * ar1 + w23 * ar2 + w33 * ar3
            for col in range(3):
                w[P_ROW + 3 * r + col, l] = ((b1 * w[FR_ROW + col, l] + b2 * w[FR_ROW + 3 + col, l]
                                              + b3 * w[FR_ROW + 6 + col, l]) + gc * cof[r][col])
        w[OUT_ROW, l] = (w[PSI_ROW, l] + w[PSI_ROW + 1, l] + w[PSI_ROW + 2, l] + w[PSI_ROW + 3, l]
                         + w[PSI_ROW + 4, l] + w[PSI_ROW + 5, l])


@njit_inline
def _moduli(w):
    """The step moduli by ``fabric_hyper._modulus`` itself, per lane."""
    for l in range(LANES):
        g = (w[G_ROW, l], w[G_ROW + 1, l], w[G_ROW + 2, l], w[G_ROW + 3, l], w[G_ROW + 4, l], w[G_ROW + 5, l])
        q = (w[Q_ROW, l], w[Q_ROW + 1, l], w[Q_ROW + 2, l])
        h = (w[H_ROW, l], w[H_ROW + 1, l], w[H_ROW + 2, l], w[H_ROW + 3, l], w[H_ROW + 4, l], w[H_ROW + 5, l])
        d = (w[D_ROW, l], w[D_ROW + 1, l], w[D_ROW + 2, l], w[D_ROW + 3, l], w[D_ROW + 4, l], w[D_ROW + 5, l])
        m1, m2, m3 = _modulus(g, q, w[J_ROW, l], w[ID_ROW, l], w[I_ROW + 3, l], w[I_ROW + 4, l], w[I_ROW + 5, l],
                              h, d)
        w[OUT_ROW + 1, l], w[OUT_ROW + 2, l], w[OUT_ROW + 3, l] = m1, m2, m3
