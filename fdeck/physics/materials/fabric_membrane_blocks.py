"""fabric_membrane's point law over blocks of ``LANES`` points with the lanes innermost, so that LLVM packs it.

``fabric_membrane.point`` costs about 55 ns per point on this machine, 64 % of a `ts` shell's cycle (36 points per
element) and 39 % of an `sm` shell's; of it the two fibre curves, the shear curve and the ``asin`` of the shear
angle take about 17 ns (table walks and kink rounding, per point a different branch), the rest is arithmetic:
fibre kinematics, the stress and the step moduli (docs/kernels.md item 11). Here that arithmetic runs as lane loops
over the rows of one work array, packed; the curves and the ``asin`` stay scalar, one lane after another, through
the same inlined helpers as the point law. Every value is formed by the same operations in the same order as
``fabric_membrane.point``, so the two give the same bits (``tests/test_fabric_membrane_blocks.py``); as in
``fabric_hyper_blocks``, a NaN at a degenerate point may differ in its sign bit, and with SVML present the block
path is not taken (its vector ``asin`` would not be libm's).

Shapes as ``fabric_membrane.evaluate`` takes them: F and P (n, n_qp, 3, 3) (a shell's corners by its levels), frame
(n, 3, 3), prm (PARAMS.size,) the section's one parameter row, psi (n, n_qp) [MPa], modulus (n, n_qp, 3) [MPa]; the
points taken in order, the last block padded by repeating the last point (its results are not written).
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.jit import njit_inline, njit_parallel, prange
from fdeck.physics.materials import blocks
from fdeck.physics.materials.fabric_membrane import PARAMS, _fibre, _moduli, _shear

LANES = blocks.LANES

# rows: F[i, j] and frame[i, j] at 3 i + j; a1, a2; I1, I2, I12; s, c, s0; per family f, psi, step slope and the
# shear's tau, Phi, step slope; P[i, j] at 3 i + j; the point's energy and three moduli. 27 KB per block.
F_ROW, FR_ROW, A_ROW, I_ROW, S_ROW, C_ROW, S0_ROW = 0, 9, 18, 24, 27, 28, 29
F1_ROW, F2_ROW, T_ROW, P_ROW, OUT_ROW = 30, 33, 36, 39, 48
ROWS = 52


def evaluate(F, frame, params, state, P, psi, modulus) -> bool:
    """The block path where ``blocks.run`` allows it (a section's broadcast parameter row, contiguous arrays, no
    SVML); returns False (nothing done) otherwise, for the caller to take the point path."""
    return blocks.run(evaluate_blocks, F, frame, params, P, psi, modulus)


@njit_parallel
def evaluate_blocks(F, frame, n_qp, prm, P, psi, modulus):
    """F, P (n, 3, 3), frame (n // n_qp, 3, 3), psi (n,), modulus (n, 3): the stages per block."""
    n = F.shape[0]
    for blk in prange((n + LANES - 1) // LANES):
        w = np.empty((ROWS, LANES))
        blocks.gather(w, F, frame, n_qp, blk, F_ROW, FR_ROW)
        _kinematics(w)
        _curves(w, prm)
        _stress_and_moduli(w, prm)
        blocks.scatter(w, P, psi, modulus, blk, P_ROW, OUT_ROW)


@njit_inline
def _kinematics(w):
    """``fabric_membrane._kinematics`` per lane, but the shear angle: a_i = F m_i, I1, I2, I12, s, c and s0."""
    for l in range(LANES):
        f00, f01, f02 = w[F_ROW, l], w[F_ROW + 1, l], w[F_ROW + 2, l]
        f10, f11, f12 = w[F_ROW + 3, l], w[F_ROW + 4, l], w[F_ROW + 5, l]
        f20, f21, f22 = w[F_ROW + 6, l], w[F_ROW + 7, l], w[F_ROW + 8, l]
        m0, m1, m2 = w[FR_ROW, l], w[FR_ROW + 1, l], w[FR_ROW + 2, l]
        n0, n1, n2 = w[FR_ROW + 3, l], w[FR_ROW + 4, l], w[FR_ROW + 5, l]
        a0 = f00 * m0 + f01 * m1 + f02 * m2
        a1 = f10 * m0 + f11 * m1 + f12 * m2
        a2 = f20 * m0 + f21 * m1 + f22 * m2
        b0 = f00 * n0 + f01 * n1 + f02 * n2
        b1 = f10 * n0 + f11 * n1 + f12 * n2
        b2 = f20 * n0 + f21 * n1 + f22 * n2
        w[A_ROW, l], w[A_ROW + 1, l], w[A_ROW + 2, l] = a0, a1, a2
        w[A_ROW + 3, l], w[A_ROW + 4, l], w[A_ROW + 5, l] = b0, b1, b2
        i1 = a0 * a0 + a1 * a1 + a2 * a2
        i2 = b0 * b0 + b1 * b1 + b2 * b2
        i12 = a0 * b0 + a1 * b1 + a2 * b2
        s = i12 / math.sqrt(i1 * i2)
        w[I_ROW, l], w[I_ROW + 1, l], w[I_ROW + 2, l] = i1, i2, i12
        w[S_ROW, l] = s
        w[S0_ROW, l] = m0 * n0 + m1 * n1 + m2 * n2
        w[C_ROW, l] = math.sqrt(max(1.0 - s * s, 0.0))


@njit_inline
def _curves(w, prm):
    """The shear angle (``asin``) and the three curves (``_fibre``, ``_shear``) lane by lane: scalar."""
    for l in range(LANES):
        f1, p1, _, k1 = _fibre(prm, PARAMS.warp_tension, PARAMS.warp_compression, 0.5 * (w[I_ROW, l] - 1.0))
        f2, p2, _, k2 = _fibre(prm, PARAMS.weft_tension, PARAMS.weft_compression, 0.5 * (w[I_ROW + 1, l] - 1.0))
        g = math.asin(w[S_ROW, l]) - math.asin(w[S0_ROW, l])
        tau, phi, _, kt = _shear(prm, g)
        w[F1_ROW, l], w[F1_ROW + 1, l], w[F1_ROW + 2, l] = f1, p1, k1
        w[F2_ROW, l], w[F2_ROW + 1, l], w[F2_ROW + 2, l] = f2, p2, k2
        w[T_ROW, l], w[T_ROW + 1, l], w[T_ROW + 2, l] = tau, phi, kt


@njit_inline
def _stress_and_moduli(w, prm):
    """P = sum_ij W_ij a_i x m_j, psi and the step moduli (by the point law's own ``_moduli``), as
    ``fabric_membrane.point``."""
    floor1, floor2 = prm[PARAMS.floor], prm[PARAMS.floor + 1]
    for l in range(LANES):
        i1, i2, s, c = w[I_ROW, l], w[I_ROW + 1, l], w[S_ROW, l], w[C_ROW, l]
        f1, k1, f2, k2 = w[F1_ROW, l], w[F1_ROW + 2, l], w[F2_ROW, l], w[F2_ROW + 2, l]
        tau, kt = w[T_ROW, l], w[T_ROW + 2, l]
        r = 1.0 / math.sqrt(i1 * i2)
        t = tau / c  # dPhi/ds
        w11 = f1 - t * s / i1
        w22 = f2 - t * s / i2
        w12 = t * r
        for row in range(3):
            ar, br = w[A_ROW + row, l], w[A_ROW + 3 + row, l]
            b1 = w11 * ar + w12 * br
            b2 = w12 * ar + w22 * br
            for col in range(3):
                w[P_ROW + 3 * row + col, l] = b1 * w[FR_ROW + col, l] + b2 * w[FR_ROW + 3 + col, l]
        w[OUT_ROW, l] = w[F1_ROW + 1, l] + w[F2_ROW + 1, l] + w[T_ROW + 1, l]
        m1, m2, second = _moduli(i1, i2, s, c, r, f1, k1, f2, k2, tau, kt, floor1, floor2)
        w[OUT_ROW + 1, l] = m1
        w[OUT_ROW + 2, l] = m2
        w[OUT_ROW + 3, l] = second
