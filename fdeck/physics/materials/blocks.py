"""What the fabric laws' block paths share (``fabric_hyper_blocks``, ``fabric_membrane_blocks``): whether a law's
array kernel may take its block path, and the transposes between the engine's point-major arrays and a block's work
rows (``LANES`` points, lanes innermost; docs/kernels.md items 9 and 11).

Shapes: F and P (n_pt, 3, 3) (the engine's (n_el, n_qp, 3, 3) seen as points), frame (n_pt // n_qp, 3, 3), psi
(n_pt,) [MPa], modulus (n_pt, 3) [MPa], the work rows w (rows, LANES).
"""

from __future__ import annotations

import numba

from fdeck.jit import njit_inline

LANES = 64
"""Points per block: the loop vectoriser packs lane loops of 64 (shorter ones are unrolled and left scalar, numba
ships LLVM's SLP vectoriser off; docs/kernels.md item 6)."""


def run(kernel, F, frame, params, P, psi, modulus) -> bool:
    """kernel(F, frame, n_qp, prm, P, psi, modulus) on the points seen as one axis, when the section's parameters
    are one broadcast row (stride 0, as the compiler and the shells build them), the arrays contiguous (so that the
    reshapes are views) and Intel's SVML absent (with it LLVM would pack the laws' log/pow/asin loops with vector
    maths whose last bits are not libm's). Returns False (nothing done) otherwise, for the point path."""
    if params.shape[0] == 0 or params.strides[0] != 0 or numba.config.USING_SVML:
        return False
    if not (F.flags.c_contiguous and P.flags.c_contiguous and psi.flags.c_contiguous and modulus.flags.c_contiguous):
        return False
    kernel(F.reshape(-1, 3, 3), frame, F.shape[1], params[0], P.reshape(-1, 3, 3), psi.reshape(-1),
           modulus.reshape(-1, 3))
    return True


@njit_inline
def gather(w, F, frame, n_qp, blk, f_row, frame_row):
    """F[i, j] of the block's points into rows f_row + 3 i + j, their elements' frame into frame_row + 3 i + j
    (scalar loads; the lanes past the last point repeat it)."""
    n = F.shape[0]
    for l in range(LANES):
        p = min(blk * LANES + l, n - 1)
        e = p // n_qp
        for i in range(3):
            for j in range(3):
                w[f_row + 3 * i + j, l] = F[p, i, j]
                w[frame_row + 3 * i + j, l] = frame[e, i, j]


@njit_inline
def scatter(w, P, psi, modulus, blk, p_row, out_row):
    """Rows p_row + 3 i + j (P) and out_row + 0..3 (psi, three moduli) back to the engine's arrays, the block's real
    points only."""
    n = P.shape[0]
    for l in range(LANES):
        p = blk * LANES + l
        if p >= n:
            break
        for i in range(3):
            for j in range(3):
                P[p, i, j] = w[p_row + 3 * i + j, l]
        psi[p] = w[out_row, l]
        modulus[p, 0] = w[out_row + 1, l]
        modulus[p, 1] = w[out_row + 2, l]
        modulus[p, 2] = w[out_row + 3, l]
