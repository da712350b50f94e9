"""The eight-point hexahedron's kinematics and forces (``full``, ``fbar``) over blocks of ``LANES`` elements, the
lanes innermost, so that LLVM packs them (AVX2/AVX-512); any law runs between the two passes.

``hex8.kinematics(_fbar)`` and ``hex8.forces(_fbar)`` take one element at a time: per point, nine sums over the
eight nodes (F = sum_a x_a (x) dN_a) and back (f_a = sum_q w_q P_q . dN_qa), scalar code. Here the same sums run for
64 elements at once, point by point: the positions gathered into one work array per block (24 rows, one per node
coordinate), the gradients read from a copy of ``dN`` in the block layout, F-bar's volume average, pressures and
forces in lane loops, the cube roots of F-bar in a scalar loop (``pow``). Every value is formed by the same
operations in the same order as in ``hex8`` (``tests/test_hex8_full_blocks.py``: the same bits), so a deck's
results do not depend on which path ran. The reference data (``dN``, ``w``, ``conn``: 1 664 B per element) are
kept in the block layout only (the group drops its ``dN``), read-only, so checkpoints do not carry them.

Shapes: blocks (n_block, ..., LANES), the last block padded by repeating the last element (its results are not
written); the engine's arrays as in ``hex8`` (F, Fbar, P (n_el, 8, 3, 3), J, ratio, p (n_el, 8), Jbar (n_el,),
fe (n_el, 8, 3)).
"""

from __future__ import annotations

import numpy as np

from fdeck.jit import njit_inline, njit_parallel, prange

LANES = 64
"""Elements per block (lane loops of 64 are what numba's LLVM packs; docs/kernels.md item 6)."""

# rows of the kinematics work array: x[a, i] at 3 a + i; the current point's F[i, j] at F + 3 i + j; J, ratio per
# point; Jbar. Point by point, so that a block's work array stays in L1 (25 KB; with all eight points' F, 58 KB
# did not, and the pass ran slower than the element-by-element one)
X_ROW, F_ROW, J_ROW, R_ROW, JBAR_ROW = 0, 24, 33, 41, 49
K_ROWS = 50
# rows of the forces work array: the current point's P and F, ratio, J, the element's Jbar; the pressures p per
# point, their weighted sum and volume; the nodal forces fe[a, i] at FE + 3 a + i (28 KB)
P_ROW, FF_ROW, A_ROW, JQ_ROW, JB_ROW, PQ_ROW, PW_ROW, V_ROW, FE_ROW = 0, 9, 18, 19, 20, 21, 29, 30, 31
F_ROWS = 55

def _to_blocks(a: np.ndarray, n_block: int) -> np.ndarray:
    """(n_el, ...) -> (n_block, prod(...), LANES), the last block padded by repeating the last element."""
    pad = n_block * LANES - len(a)
    a = np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]) if pad else a
    return np.ascontiguousarray(a.reshape(n_block, LANES, -1).transpose(0, 2, 1))


class Blocks:
    """The block layout of one eight-point group: conn_t (n_block, 8, LANES) int64, dN_t (n_block, 8 * 24, LANES)
    with dN[e, q, a, i] at row 24 q + 3 a + i, w_t (n_block, 8, LANES); read-only copies."""

    def __init__(self, conn, dN, w):
        n = len(conn)
        self.n_el = n
        n_block = -(-n // LANES)
        self.conn_t = _to_blocks(np.asarray(conn, np.int64), n_block)
        self.dN_t = _to_blocks(np.asarray(dN, float).reshape(n, 8 * 24), n_block)
        self.w_t = _to_blocks(np.asarray(w, float), n_block)
        for a in (self.conn_t, self.dN_t, self.w_t):
            a.setflags(write=False)
        # stand-ins for the F-bar arrays of a ``full`` group (never read or written there; the kernels' types)
        self._no_fbar = np.zeros((1, 8, 3, 3)), np.zeros((1, 8)), np.zeros(1)

    def gradients(self) -> np.ndarray:
        """dN (n_el, 8, 8, 3) in the engine's layout, rebuilt from the block copy (for tests and benchmarks)."""
        return np.ascontiguousarray(self.dN_t.transpose(0, 2, 1).reshape(-1, 8, 8, 3)[:self.n_el])

    def kinematics(self, x, F, J) -> None:
        F4, q2, e1 = self._no_fbar
        kinematics_blocks(x, self.conn_t, self.dN_t, self.w_t, self.n_el, False, F, J, F4, e1, q2)

    def kinematics_fbar(self, x, F, J, Fbar, Jbar, ratio) -> None:
        kinematics_blocks(x, self.conn_t, self.dN_t, self.w_t, self.n_el, True, F, J, Fbar, Jbar, ratio)

    def forces(self, P, fe) -> None:
        F4, q2, e1 = self._no_fbar
        forces_blocks(P, self.dN_t, self.w_t, self.n_el, False, F4, q2, e1, q2, q2, fe)

    def forces_fbar(self, F, J, Jbar, ratio, P, p, fe) -> None:
        forces_blocks(P, self.dN_t, self.w_t, self.n_el, True, F, J, Jbar, ratio, p, fe)


@njit_parallel
def kinematics_blocks(x, conn_t, dN_t, w_t, n_el, fbar, F, J, Fbar, Jbar, ratio):
    """``hex8.kinematics`` (fbar False: F, J) or ``hex8.kinematics_fbar`` (also Fbar, Jbar, ratio) over blocks."""
    for blk in prange(conn_t.shape[0]):
        wk = np.empty((K_ROWS, LANES))
        for a in range(8):  # gather: scalar loads
            for l in range(LANES):
                n = conn_t[blk, a, l]
                wk[X_ROW + 3 * a, l] = x[n, 0]
                wk[X_ROW + 3 * a + 1, l] = x[n, 1]
                wk[X_ROW + 3 * a + 2, l] = x[n, 2]
        d = dN_t[blk]
        e0 = blk * LANES
        n_here = min(LANES, n_el - e0)
        for q in range(8):
            _gradient(wk, d, q)
            for l in range(n_here):  # back to the engine's layout
                for i in range(3):
                    for j in range(3):
                        F[e0 + l, q, i, j] = wk[F_ROW + 3 * i + j, l]
                J[e0 + l, q] = wk[J_ROW + q, l]
        if fbar:
            _average(wk, w_t[blk])
            for l in range(n_here):
                e = e0 + l
                Jbar[e] = wk[JBAR_ROW, l]
                for q in range(8):
                    r = wk[R_ROW + q, l]
                    ratio[e, q] = r
                    for i in range(3):
                        for j in range(3):
                            Fbar[e, q, i, j] = r * F[e, q, i, j]


@njit_inline
def _gradient(wk, d, q):
    """F_q = sum_a x_a (x) dN_qa into the F rows and J_q = det F_q (``hex8._deformation_gradients``)."""
    o = 24 * q
    for l in range(LANES):
        f00 = 0.0
        f01 = 0.0
        f02 = 0.0
        f10 = 0.0
        f11 = 0.0
        f12 = 0.0
        f20 = 0.0
        f21 = 0.0
        f22 = 0.0
        for a in range(8):
            x0, x1, x2 = wk[X_ROW + 3 * a, l], wk[X_ROW + 3 * a + 1, l], wk[X_ROW + 3 * a + 2, l]
            d0, d1, d2 = d[o + 3 * a, l], d[o + 3 * a + 1, l], d[o + 3 * a + 2, l]
            f00 += x0 * d0
            f01 += x0 * d1
            f02 += x0 * d2
            f10 += x1 * d0
            f11 += x1 * d1
            f12 += x1 * d2
            f20 += x2 * d0
            f21 += x2 * d1
            f22 += x2 * d2
        wk[F_ROW, l], wk[F_ROW + 1, l], wk[F_ROW + 2, l] = f00, f01, f02
        wk[F_ROW + 3, l], wk[F_ROW + 4, l], wk[F_ROW + 5, l] = f10, f11, f12
        wk[F_ROW + 6, l], wk[F_ROW + 7, l], wk[F_ROW + 8, l] = f20, f21, f22
        wk[J_ROW + q, l] = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
                            + f02 * (f10 * f21 - f11 * f20))


@njit_inline
def _average(wk, w):
    """F-bar: Jbar = sum_q w_q J_q / V0 and ratio_q = (Jbar / J_q)^(1/3) (``hex8.kinematics_fbar``)."""
    for l in range(LANES):
        vol = 0.0
        jw = 0.0
        for q in range(8):
            vol += w[q, l]
            jw += w[q, l] * wk[J_ROW + q, l]
        wk[JBAR_ROW, l] = jw / vol
    for l in range(LANES):  # the cube roots: scalar (libm pow)
        jbar = wk[JBAR_ROW, l]
        for q in range(8):
            jq = wk[J_ROW + q, l]
            wk[R_ROW + q, l] = (jbar / jq) ** (1.0 / 3.0) if jq > 0.0 else np.nan


@njit_parallel
def forces_blocks(P, dN_t, w_t, n_el, fbar, F, J, Jbar, ratio, p, fe):
    """``hex8.forces`` (fbar False: from P) or ``hex8.forces_fbar`` (from Pbar = P, F, J, Jbar, ratio; writes the
    pressures p) over blocks, into fe."""
    for blk in prange(dN_t.shape[0]):
        wf = np.empty((F_ROWS, LANES))
        d, w = dN_t[blk], w_t[blk]
        e0 = blk * LANES
        for k in range(24):
            for l in range(LANES):
                wf[FE_ROW + k, l] = 0.0
        if fbar:  # the pressures and their volume mean (``hex8.mean_pressure``), point by point
            for l in range(LANES):
                wf[PW_ROW, l] = 0.0
                wf[V_ROW, l] = 0.0
            for q in range(8):
                _load_point(wf, P, F, J, Jbar, ratio, fbar, e0, n_el, q)
                for l in range(LANES):
                    pf = 0.0
                    for k in range(9):
                        pf += wf[P_ROW + k, l] * wf[FF_ROW + k, l]
                    pq = wf[A_ROW, l] * pf / 3.0
                    wf[PQ_ROW + q, l] = pq
                    wf[PW_ROW, l] += w[q, l] * pq
                    wf[V_ROW, l] += w[q, l]
        for q in range(8):
            _load_point(wf, P, F, J, Jbar, ratio, fbar, e0, n_el, q)
            if fbar:
                _effective_stress(wf, q)
            _add_point(wf, d, w, q)
        for l in range(min(LANES, n_el - e0)):  # back to the engine's layout
            e = e0 + l
            for a in range(8):
                fe[e, a, 0] = wf[FE_ROW + 3 * a, l]
                fe[e, a, 1] = wf[FE_ROW + 3 * a + 1, l]
                fe[e, a, 2] = wf[FE_ROW + 3 * a + 2, l]
            if fbar:
                for q in range(8):
                    p[e, q] = wf[PQ_ROW + q, l]


@njit_inline
def _load_point(wf, P, F, J, Jbar, ratio, fbar, e0, n_el, q):
    """Point q's P (and for F-bar its F, ratio, J and the element's Jbar) of the block's elements into their rows
    (scalar loads; the padded lanes repeat the last element)."""
    for l in range(LANES):
        e = min(e0 + l, n_el - 1)
        for i in range(3):
            for j in range(3):
                wf[P_ROW + 3 * i + j, l] = P[e, q, i, j]
        if fbar:
            for i in range(3):
                for j in range(3):
                    wf[FF_ROW + 3 * i + j, l] = F[e, q, i, j]
            wf[A_ROW, l] = ratio[e, q]
            wf[JQ_ROW, l] = J[e, q]
            wf[JB_ROW, l] = Jbar[e]


@njit_inline
def _effective_stress(wf, q):
    """F-bar: P_eff = ratio P + c cof(F) with c = (pavg J / Jbar - p) / J in the P rows (``hex8.forces_fbar``)."""
    for l in range(LANES):
        pavg = wf[PW_ROW, l] / wf[V_ROW, l]
        a = wf[A_ROW, l]
        jq = wf[JQ_ROW, l]
        c = (pavg / wf[JB_ROW, l] * jq - wf[PQ_ROW + q, l]) / jq
        o, r = P_ROW, FF_ROW
        f00, f01, f02 = wf[r, l], wf[r + 1, l], wf[r + 2, l]
        f10, f11, f12 = wf[r + 3, l], wf[r + 4, l], wf[r + 5, l]
        f20, f21, f22 = wf[r + 6, l], wf[r + 7, l], wf[r + 8, l]
        wf[o, l] = a * wf[o, l] + c * (f11 * f22 - f12 * f21)
        wf[o + 1, l] = a * wf[o + 1, l] + c * (f12 * f20 - f10 * f22)
        wf[o + 2, l] = a * wf[o + 2, l] + c * (f10 * f21 - f11 * f20)
        wf[o + 3, l] = a * wf[o + 3, l] + c * (f21 * f02 - f22 * f01)
        wf[o + 4, l] = a * wf[o + 4, l] + c * (f22 * f00 - f20 * f02)
        wf[o + 5, l] = a * wf[o + 5, l] + c * (f20 * f01 - f21 * f00)
        wf[o + 6, l] = a * wf[o + 6, l] + c * (f01 * f12 - f02 * f11)
        wf[o + 7, l] = a * wf[o + 7, l] + c * (f02 * f10 - f00 * f12)
        wf[o + 8, l] = a * wf[o + 8, l] + c * (f00 * f11 - f01 * f10)


@njit_inline
def _add_point(wf, d, w, q):
    """fe[a] += w_q P_q . dN_qa for the eight nodes (``hex8._add_point_forces``), P_q from its rows."""
    o = 24 * q
    for l in range(LANES):
        wq = w[q, l]
        p00, p01, p02 = wf[P_ROW, l], wf[P_ROW + 1, l], wf[P_ROW + 2, l]
        p10, p11, p12 = wf[P_ROW + 3, l], wf[P_ROW + 4, l], wf[P_ROW + 5, l]
        p20, p21, p22 = wf[P_ROW + 6, l], wf[P_ROW + 7, l], wf[P_ROW + 8, l]
        for a in range(8):
            d0, d1, d2 = wq * d[o + 3 * a, l], wq * d[o + 3 * a + 1, l], wq * d[o + 3 * a + 2, l]
            wf[FE_ROW + 3 * a, l] += p00 * d0 + p01 * d1 + p02 * d2
            wf[FE_ROW + 3 * a + 1, l] += p10 * d0 + p11 * d1 + p12 * d2
            wf[FE_ROW + 3 * a + 2, l] += p20 * d0 + p21 * d1 + p22 * d2
