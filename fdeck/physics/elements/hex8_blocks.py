"""The one-point hexahedron (``reduced``) with ``linear_elastic``, fused and vectorised over blocks of elements.

Today's general path (``hex8``) updates the elements in four passes, one element at a time (kinematics, law,
forces, hourglass). For this one pairing the same arithmetic runs here once per block of ``LANES`` elements with
the lanes innermost, which lets LLVM turn it into packed (AVX2) instructions: positions (and velocities, for the
viscous hourglass) gathered into one work array per block, F and the law in one lane loop, the forces and the
hourglass forces in lane loops over 1-D rows. Every value is formed by the same operations in the same order as
``hex8.kinematics``, ``elastic.point``, ``hex8.forces`` and ``hex8.hourglass`` (the bits are the same:
``tests/test_hex8_blocks.py``), so a deck's results do not depend on which path ran.

Why this shape (docs/kernels.md, item 8): numba vectorises a lane loop only while it writes and reads few arrays
(LLVM's runtime alias checks), hence one work and one reference array per block. The reference data (b, V0,
gamma, the hourglass coefficients: 472 B per element) are kept a second time in the block layout, read-only (so
checkpoints, which skip read-only arrays, do not carry them). The law is ``elastic.stress``, the one definition
``elastic.point`` evaluates too. Measured on a loaded machine (``benchmarks/simd_fused_probe.py`` for the kernel
alone, the group's ``update`` in the engine: docs/kernels.md): the element update 1.5x (in the engine, which also
stores F, P and the per-element values) to about 2.5x (the probe's bare kernel) faster than the four passes at
10 000 elements.

Shapes: blocks (n_block, rows, LANES); the engine's arrays as in ``hex8`` (F and P (n_el, 1, 3, 3), fe (n_el, 8, 3),
psi and J (n_el, 1), modulus (n_el, 1, 3), e_hg and p_hg (n_el,)), written at the end of each block.
"""

from __future__ import annotations

import numpy as np

from fdeck.jit import njit_inline, njit_parallel, prange
from fdeck.physics.materials import elastic

LANES = 64
# rows of the reference array (n_block, REF_ROWS, LANES)
B_ROW, V_ROW, G_ROW, K_ROW, C_ROW = 0, 24, 25, 57, 58  # b[a, i] (24), V0, gamma[alpha, a] (32), k_hg, c_hg
REF_ROWS = 59
# rows of the per-block work array: x[a, i] (24), v[a, i] (24), P (9), psi, J, modulus, s (12), r (12), F (9),
# e_hg, p_hg
X_ROW, VEL_ROW, P_ROW, PSI_ROW, J_ROW, M_ROW, S_ROW, R_ROW, F_ROW, EH_ROW, PH_ROW = (0, 24, 48, 57, 58, 59, 60, 72,
                                                                                 84, 93, 94)
WORK_ROWS = 95


def eligible(formulation: str, material, params: np.ndarray) -> bool:
    """This path serves a non-empty ``reduced`` group of ``linear_elastic`` (its kernel, not only its name) whose
    Lame constants are one pair for the group."""
    return (formulation == "reduced" and getattr(material, "evaluate", None) is elastic.evaluate
            and len(params) > 0 and bool(np.all(params == params[:1])))


def _to_blocks(a: np.ndarray, n_block: int) -> np.ndarray:
    """(n_el, ...) -> (n_block, prod(...), LANES), the last block padded by repeating the last element."""
    pad = n_block * LANES - len(a)
    a = np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]) if pad else a
    return np.ascontiguousarray(a.reshape(n_block, LANES, -1).transpose(0, 2, 1))


class Blocks:
    """The block layout of one group: conn_t (n_block, 8, LANES) int64, ref_t (n_block, REF_ROWS, LANES), the
    Lame constants, and which hourglass sums the group needs (stiffness: positions, viscous: velocities)."""

    def __init__(self, conn, b, V0, gamma, k_hg, c_hg, params):
        n = len(conn)
        self.n_el = n
        n_block = -(-n // LANES)
        self.conn_t = _to_blocks(np.asarray(conn, np.int64), n_block)
        ref = np.concatenate([b.reshape(n, 24), V0[:, None], gamma.reshape(n, 32), k_hg[:, None], c_hg[:, None]],
                             axis=1)
        self.ref_t = _to_blocks(ref, n_block)
        # copies of the group's constants (built once: hex8 never changes them after construction); read-only, so a
        # checkpoint does not carry them (snapshots skip read-only arrays) and nothing writes them by mistake
        self.conn_t.setflags(write=False)
        self.ref_t.setflags(write=False)
        self.lam, self.mu = float(params[0, elastic.PARAMS.lam]), float(params[0, elastic.PARAMS.mu])
        self.use_k, self.use_c = bool(np.any(k_hg != 0.0)), bool(np.any(c_hg != 0.0))
        # hex8 skips an element's sums where its coefficient is zero; per lane only if the group mixes zero and not
        self.mixed = bool((self.use_k and not np.all(k_hg != 0.0)) or (self.use_c and not np.all(c_hg != 0.0)))

    def update(self, x, v, F, P, fe, psi, J, modulus, e_hg, p_hg) -> None:
        """The outputs of the four passes, in the engine's arrays."""
        update_blocks(x, v, self.conn_t, self.ref_t, self.lam, self.mu, self.use_k, self.use_c, self.mixed,
                      self.n_el, F, P, fe, psi, J, modulus, e_hg, p_hg)


@njit_parallel
def update_blocks(x, v, conn_t, ref_t, lam, mu, use_k, use_c, mixed, n_el, F, P, fe, psi, J, modulus, e_hg,
                  p_hg):
    """The reduced elements' update over blocks (arrays as in ``Blocks`` and the module docstring)."""
    for blk in prange(conn_t.shape[0]):
        w = np.empty((WORK_ROWS, LANES))
        r = ref_t[blk]
        f = np.empty((24, LANES))
        for a in range(8):  # gather: scalar loads
            for l in range(LANES):
                n = conn_t[blk, a, l]
                w[X_ROW + 3 * a, l] = x[n, 0]
                w[X_ROW + 3 * a + 1, l] = x[n, 1]
                w[X_ROW + 3 * a + 2, l] = x[n, 2]
                if use_c:
                    w[VEL_ROW + 3 * a, l] = v[n, 0]
                    w[VEL_ROW + 3 * a + 1, l] = v[n, 1]
                    w[VEL_ROW + 3 * a + 2, l] = v[n, 2]
        _kinematics_and_law(w, r, lam, mu)
        _forces(w, r, f)
        if use_k or use_c:  # (without hourglass control hex8 adds nothing, not even zeros: -0.0 stays)
            _hourglass(w, r, f, use_k, use_c, mixed)
        else:
            for l in range(LANES):
                w[EH_ROW, l] = 0.0
                w[PH_ROW, l] = 0.0
        for l in range(LANES):  # back to the engine's layout, while the block is in L1
            e = blk * LANES + l
            if e >= n_el:
                break
            for a in range(8):
                fe[e, a, 0] = f[3 * a, l]
                fe[e, a, 1] = f[3 * a + 1, l]
                fe[e, a, 2] = f[3 * a + 2, l]
            for i in range(3):
                for j in range(3):
                    F[e, 0, i, j] = w[F_ROW + 3 * i + j, l]
                    P[e, 0, i, j] = w[P_ROW + 3 * i + j, l]
            psi[e, 0] = w[PSI_ROW, l]
            J[e, 0] = w[J_ROW, l]
            modulus[e, 0, 0] = w[M_ROW, l]
            modulus[e, 0, 1] = w[M_ROW, l]
            modulus[e, 0, 2] = w[M_ROW, l]
            e_hg[e] = w[EH_ROW, l]
            p_hg[e] = w[PH_ROW, l]


@njit_inline
def _kinematics_and_law(w, r, lam, mu):
    """F = sum_a x_a (x) b_a, J = det F, and St Venant-Kirchhoff's P, psi and step modulus (``elastic.stress``)."""
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
            x0, x1, x2 = w[X_ROW + 3 * a, l], w[X_ROW + 3 * a + 1, l], w[X_ROW + 3 * a + 2, l]
            d0, d1, d2 = r[B_ROW + 3 * a, l], r[B_ROW + 3 * a + 1, l], r[B_ROW + 3 * a + 2, l]
            f00 += x0 * d0
            f01 += x0 * d1
            f02 += x0 * d2
            f10 += x1 * d0
            f11 += x1 * d1
            f12 += x1 * d2
            f20 += x2 * d0
            f21 += x2 * d1
            f22 += x2 * d2
        w[F_ROW, l], w[F_ROW + 1, l], w[F_ROW + 2, l] = f00, f01, f02
        w[F_ROW + 3, l], w[F_ROW + 4, l], w[F_ROW + 5, l] = f10, f11, f12
        w[F_ROW + 6, l], w[F_ROW + 7, l], w[F_ROW + 8, l] = f20, f21, f22
        w[J_ROW, l] = f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20) + f02 * (f10 * f21 - f11 * f20)
        p00, p01, p02, p10, p11, p12, p20, p21, p22, psi, m = elastic.stress(
            f00, f01, f02, f10, f11, f12, f20, f21, f22, lam, mu)
        w[P_ROW, l], w[P_ROW + 1, l], w[P_ROW + 2, l] = p00, p01, p02
        w[P_ROW + 3, l], w[P_ROW + 4, l], w[P_ROW + 5, l] = p10, p11, p12
        w[P_ROW + 6, l], w[P_ROW + 7, l], w[P_ROW + 8, l] = p20, p21, p22
        w[PSI_ROW, l] = psi
        w[M_ROW, l] = m


@njit_inline
def _forces(w, r, f):
    """f[3 a + i] = V0 P_i . b_a (``hex8._nodal_forces`` with one point), rows as 1-D views, lanes innermost."""
    wq = r[V_ROW]
    for a in range(8):
        b0, b1, b2 = r[B_ROW + 3 * a], r[B_ROW + 3 * a + 1], r[B_ROW + 3 * a + 2]
        for i in range(3):
            p0, p1, p2, o = w[P_ROW + 3 * i], w[P_ROW + 3 * i + 1], w[P_ROW + 3 * i + 2], f[3 * a + i]
            for l in range(LANES):
                o[l] = 0.0 + (p0[l] * (wq[l] * b0[l]) + p1[l] * (wq[l] * b1[l]) + p2[l] * (wq[l] * b2[l]))


@njit_inline
def _hourglass(w, r, f, use_k, use_c, mixed):
    """``hex8.hourglass_element`` over the block: the four modes' sums of positions (stiffness) and velocities
    (viscous), zero where the element's coefficient is zero (as hex8 skips them), then k s + c r into the rows
    S_ROW, and the forces added mode by mode in hex8's order."""
    for m in range(12):
        for l in range(LANES):
            w[S_ROW + m, l] = 0.0
            w[R_ROW + m, l] = 0.0
    if use_k:
        _mode_sums(w, r, X_ROW, S_ROW)
    if use_c:
        _mode_sums(w, r, VEL_ROW, R_ROW)
    if mixed:  # hex8 takes no sums where the coefficient is zero
        for m in range(12):
            for l in range(LANES):
                if r[K_ROW, l] == 0.0:
                    w[S_ROW + m, l] = 0.0
                if r[C_ROW, l] == 0.0:
                    w[R_ROW + m, l] = 0.0
    for l in range(LANES):  # energies (hex8._squares): sum_m scale q_m q_m in order from zero
        w[EH_ROW, l] = 0.0
        w[PH_ROW, l] = 0.0
    for m in range(12):
        for l in range(LANES):
            w[EH_ROW, l] += 0.5 * r[K_ROW, l] * w[S_ROW + m, l] * w[S_ROW + m, l]
            w[PH_ROW, l] += r[C_ROW, l] * w[R_ROW + m, l] * w[R_ROW + m, l]
    # k s + c r into the velocity rows (no longer needed); the sums stay in S_ROW / R_ROW for the energies
    for m in range(12):
        for l in range(LANES):
            w[VEL_ROW + m, l] = r[K_ROW, l] * w[S_ROW + m, l] + r[C_ROW, l] * w[R_ROW + m, l]
    for a in range(8):
        g0, g1, g2, g3 = r[G_ROW + a], r[G_ROW + 8 + a], r[G_ROW + 16 + a], r[G_ROW + 24 + a]
        for i in range(3):
            h0, h1, h2, h3 = w[VEL_ROW + i], w[VEL_ROW + 3 + i], w[VEL_ROW + 6 + i], w[VEL_ROW + 9 + i]
            o = f[3 * a + i]
            for l in range(LANES):
                t = o[l]
                t += h0[l] * g0[l]
                t += h1[l] * g1[l]
                t += h2[l] * g2[l]
                t += h3[l] * g3[l]
                o[l] = t


@njit_inline
def _mode_sums(w, r, src, dst):
    """w[dst + 3 m + i] += sum_a w[src + 3 a + i] gamma[m, a], over the nodes in order (``hex8._hourglass_sums``)."""
    for a in range(8):
        for l in range(LANES):
            y0, y1, y2 = w[src + 3 * a, l], w[src + 3 * a + 1, l], w[src + 3 * a + 2, l]
            for m in range(4):
                g = r[G_ROW + 8 * m + a, l]
                w[dst + 3 * m, l] += y0 * g
                w[dst + 3 * m + 1, l] += y1 * g
                w[dst + 3 * m + 2, l] += y2 * g
