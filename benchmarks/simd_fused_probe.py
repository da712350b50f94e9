"""The reduced hexahedron with linear elasticity fused and vectorised over blocks of elements (issue 10's SIMD
route; a probe, not part of the engine or the tests).

    python benchmarks/simd_fused_probe.py                  # 10 000 elements, 1 thread, 3 rounds
    python benchmarks/simd_fused_probe.py --size 102400 --threads 2
    python benchmarks/simd_fused_probe.py --size 102400 --copy  # each block's reference data copied linearly first

Today's engine runs the element update as four passes over the elements, one element at a time (kinematics, the
law, forces, hourglass: ``hex8`` and ``elastic``), then the deterministic gather into the nodes. Here the same
arithmetic runs once per block of 64 elements, lanes innermost, in lane loops per block (positions gathered into
the block's work array, then F + law, forces per node, hourglass sums, hourglass forces). Every value is formed by
the same operations in the same order as in today's kernels, so the outputs must be the same bits (checked here:
element forces, energies, J, moduli and the gathered nodal forces).

What it showed (docs/kernels.md, item 8): numba vectorises a lane loop (no fastmath, SLP vectoriser off:
``simd_probe.py``) only while the arrays it writes and reads are few: F + law writing two output arrays and reading
three vectorised, writing three did not (consistent with LLVM's limit on runtime alias checks, 8 pointer pairs by
default); with one work array per block (rows at constant offsets) and one reference array, it does. The forces
and hourglass forces vectorise best as 1-D row views with the lanes innermost. Two gathers are timed: one reading
the block layout (a node's three components in three cache lines) and today's ``gather_add`` after the block
stores its forces in the engine's layout (n_el, 8, 3).

Prints the packed and scalar double multiply/add instructions of the block kernel (none when numba loads it from
its cache), the same-bits check, and per round the time per element of today's passes + gather, of the blocks
with either gather, and of the element updates alone.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fdeck.compile.mesh import block  # noqa: E402
from fdeck.engine.gather import gather_add, node_slots  # noqa: E402
from fdeck.jit import FLAGS  # noqa: E402
from fdeck.physics.elements import hex8  # noqa: E402
from fdeck.physics.materials import elastic  # noqa: E402
from kernel_parts import best_us_per_element  # noqa: E402
from simd_probe import packed_and_scalar  # noqa: E402

LANES = 64
# rows of the per-block reference array (n_block, REF_ROWS, LANES)
B_ROW, V_ROW, G_ROW, K_ROW = 0, 24, 25, 57  # uniform gradients b[a, i] (24), V0, gamma[alpha, a] (32), k_hg
REF_ROWS = 58
# rows of the per-block work array (REF_ROWS is unrelated): x[a, i] (24), P (9), psi, J, modulus, e_hg, q (12)
X_ROW, P_ROW, PSI_ROW, J_ROW, M_ROW, E_ROW, Q_ROW = 0, 24, 33, 34, 35, 36, 37
WORK_ROWS = 49


@numba.njit(parallel=True, **FLAGS)
def fused_blocks(x, conn_t, ref_t, lam, mu, fe_t, out_t, fe, copy):
    """One pass over blocks of LANES elements: fe_t (n_block, 24, LANES) element forces, rows 3 a + i; out_t
    (n_block, 4, LANES) psi, J, modulus, e_hg. conn_t (n_block, 8, LANES), ref_t (n_block, REF_ROWS, LANES).
    With fe (n_block LANES, 8, 3) not empty, the forces are also stored there, the engine's layout (``gather_add``
    reads each element's 24 values from one place; the block layout puts a node's three in three cache lines).
    With copy, each block's reference chunk is first copied linearly into a local array (one stream to prefetch)."""
    for blk in numba.prange(conn_t.shape[0]):
        w = np.empty((WORK_ROWS, LANES))
        r = ref_t[blk]
        if copy:
            r = np.empty((REF_ROWS, LANES))
            for k in range(REF_ROWS):
                for l in range(LANES):
                    r[k, l] = ref_t[blk, k, l]
        f = fe_t[blk]
        for a in range(8):  # gather: scalar loads
            for l in range(LANES):
                n = conn_t[blk, a, l]
                w[X_ROW + 3 * a, l] = x[n, 0]
                w[X_ROW + 3 * a + 1, l] = x[n, 1]
                w[X_ROW + 3 * a + 2, l] = x[n, 2]
        for l in range(LANES):  # F, det F and the law (hex8._deformation_gradients, elastic.point)
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
            w[J_ROW, l] = (f00 * (f11 * f22 - f12 * f21) - f01 * (f10 * f22 - f12 * f20)
                           + f02 * (f10 * f21 - f11 * f20))
            e00 = 0.5 * (f00 * f00 + f10 * f10 + f20 * f20 - 1.0)
            e11 = 0.5 * (f01 * f01 + f11 * f11 + f21 * f21 - 1.0)
            e22 = 0.5 * (f02 * f02 + f12 * f12 + f22 * f22 - 1.0)
            e01 = 0.5 * (f00 * f01 + f10 * f11 + f20 * f21)
            e12 = 0.5 * (f01 * f02 + f11 * f12 + f21 * f22)
            e02 = 0.5 * (f00 * f02 + f10 * f12 + f20 * f22)
            tr = e00 + e11 + e22
            s00, s11, s22 = lam * tr + 2.0 * mu * e00, lam * tr + 2.0 * mu * e11, lam * tr + 2.0 * mu * e22
            s01, s12, s02 = 2.0 * mu * e01, 2.0 * mu * e12, 2.0 * mu * e02
            w[P_ROW, l] = f00 * s00 + f01 * s01 + f02 * s02
            w[P_ROW + 1, l] = f00 * s01 + f01 * s11 + f02 * s12
            w[P_ROW + 2, l] = f00 * s02 + f01 * s12 + f02 * s22
            w[P_ROW + 3, l] = f10 * s00 + f11 * s01 + f12 * s02
            w[P_ROW + 4, l] = f10 * s01 + f11 * s11 + f12 * s12
            w[P_ROW + 5, l] = f10 * s02 + f11 * s12 + f12 * s22
            w[P_ROW + 6, l] = f20 * s00 + f21 * s01 + f22 * s02
            w[P_ROW + 7, l] = f20 * s01 + f21 * s11 + f22 * s12
            w[P_ROW + 8, l] = f20 * s02 + f21 * s12 + f22 * s22
            w[PSI_ROW, l] = 0.5 * lam * tr * tr + mu * (e00 * e00 + e11 * e11 + e22 * e22
                                                        + 2.0 * (e01 * e01 + e12 * e12 + e02 * e02))
            c_max = 1.0 + 2.0 * max(e00 + abs(e01) + abs(e02), e11 + abs(e01) + abs(e12), e22 + abs(e02) + abs(e12))
            sb = max(s00 + abs(s01) + abs(s02), s11 + abs(s01) + abs(s12), s22 + abs(s02) + abs(s12))
            w[M_ROW, l] = max(0.0, sb) + (3.0 * lam + 2.0 * mu) * c_max
        wq = r[V_ROW]
        for a in range(8):  # forces (hex8._nodal_forces, one point); rows as 1-D views, lanes innermost
            b0, b1, b2 = r[B_ROW + 3 * a], r[B_ROW + 3 * a + 1], r[B_ROW + 3 * a + 2]
            for i in range(3):
                p0, p1, p2, o = w[P_ROW + 3 * i], w[P_ROW + 3 * i + 1], w[P_ROW + 3 * i + 2], f[3 * a + i]
                for l in range(LANES):
                    o[l] = 0.0 + (p0[l] * (wq[l] * b0[l]) + p1[l] * (wq[l] * b1[l]) + p2[l] * (wq[l] * b2[l]))
        for l in range(LANES):  # hourglass sums (hex8._hourglass_sums), mode-major
            for m in range(12):
                w[Q_ROW + m, l] = 0.0
        for a in range(8):
            for l in range(LANES):
                x0, x1, x2 = w[X_ROW + 3 * a, l], w[X_ROW + 3 * a + 1, l], w[X_ROW + 3 * a + 2, l]
                for m in range(4):
                    g = r[G_ROW + 8 * m + a, l]
                    w[Q_ROW + 3 * m, l] += x0 * g
                    w[Q_ROW + 3 * m + 1, l] += x1 * g
                    w[Q_ROW + 3 * m + 2, l] += x2 * g
        for l in range(LANES):  # stored energy (hex8._squares) and k q (+ c r with c = 0, as hex8 forms it)
            k = r[K_ROW, l]
            t = 0.0
            for m in range(12):
                t += 0.5 * k * w[Q_ROW + m, l] * w[Q_ROW + m, l]
            w[E_ROW, l] = t
            for m in range(12):
                w[Q_ROW + m, l] = k * w[Q_ROW + m, l] + 0.0 * 0.0
        for a in range(8):  # hourglass forces (hex8.hourglass_element), the four modes added in order
            g0, g1, g2, g3 = r[G_ROW + a], r[G_ROW + 8 + a], r[G_ROW + 16 + a], r[G_ROW + 24 + a]
            for i in range(3):
                h0, h1, h2, h3, o = w[Q_ROW + i], w[Q_ROW + 3 + i], w[Q_ROW + 6 + i], w[Q_ROW + 9 + i], f[3 * a + i]
                for l in range(LANES):
                    v = o[l]
                    v += h0[l] * g0[l]
                    v += h1[l] * g1[l]
                    v += h2[l] * g2[l]
                    v += h3[l] * g3[l]
                    o[l] = v
        if fe.shape[0] > 0:  # transposed stores, while the block's forces are in L1
            for l in range(LANES):
                e = blk * LANES + l
                for a in range(8):
                    fe[e, a, 0] = f[3 * a, l]
                    fe[e, a, 1] = f[3 * a + 1, l]
                    fe[e, a, 2] = f[3 * a + 2, l]
        for l in range(LANES):
            out_t[blk, 0, l] = w[PSI_ROW, l]
            out_t[blk, 1, l] = w[J_ROW, l]
            out_t[blk, 2, l] = w[M_ROW, l]
            out_t[blk, 3, l] = w[E_ROW, l]


def block_slots(slots: np.ndarray) -> np.ndarray:
    """Each slot e * 8 + a of ``engine.gather.node_slots`` as the flat index of its x row in the block layout
    (n_block, 24, LANES): (e // LANES) * 24 LANES + 3 a LANES + e % LANES (no division per slot and cycle)."""
    e, a = np.divmod(slots, 8)
    return (e // LANES) * 24 * LANES + 3 * a * LANES + e % LANES


@numba.njit(parallel=True, **FLAGS)
def gather_blocks(fe_t, ptr, offsets, f):
    """f (n_node, 3) += the element forces of fe_t (n_block, 24, LANES) over each node's slots, in slot order
    (engine.gather.gather_add's sums on the block layout; offsets from ``block_slots``)."""
    flat = fe_t.reshape(fe_t.size)
    for n in numba.prange(f.shape[0]):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for i in range(ptr[n], ptr[n + 1]):
            o = offsets[i]
            s0 += flat[o]
            s1 += flat[o + LANES]
            s2 += flat[o + 2 * LANES]
        f[n, 0] += s0
        f[n, 1] += s1
        f[n, 2] += s2


def to_blocks(a: np.ndarray, n_block: int) -> np.ndarray:
    """(n_el, ...) -> (n_block, prod(...), LANES), padded by repeating the last element."""
    pad = n_block * LANES - len(a)
    a = np.concatenate([a, np.repeat(a[-1:], pad, axis=0)]) if pad else a
    return np.ascontiguousarray(a.reshape(n_block, LANES, -1).transpose(0, 2, 1))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=10_000, help="elements (a 50 x n x 4 block)")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--copy", action="store_true", help="copy each block's reference chunk into L1 first")
    args = ap.parse_args()
    numba.set_num_threads(args.threads)
    ny = max(1, args.size // 200)
    mesh = block([0, 0, 0], [50, ny, 4], divisions=[50, ny, 4])
    X, conn = mesh.X, np.ascontiguousarray(mesh.cells["hexahedron"], np.int64)
    n, n_node = len(conn), len(X)
    geo = hex8.prepare(X, conn)
    b, V0, gamma = geo["b"], geo["V0"], geo["gamma"]
    E, nu = 210_000.0, 0.3
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    params = np.broadcast_to(np.array([lam, mu]), (n, 2))
    k_hg = 0.05 * (lam + 2 * mu) * V0 * np.einsum("eai,eai->e", b, b) / 8.0
    rng = np.random.default_rng(3)
    x = X + 0.01 * rng.normal(size=X.shape)
    v = np.zeros_like(x)
    ptr, slots = node_slots(conn, n_node)

    # today's passes (the engine's arrays, reduced: one point with the uniform gradient and the whole volume)
    dN, w = b[:, None], V0[:, None].copy()
    F, J, P = np.zeros((n, 1, 3, 3)), np.zeros((n, 1)), np.zeros((n, 1, 3, 3))
    psi, mod, state, frame = np.zeros((n, 1)), np.zeros((n, 1, 3)), np.zeros((n, 1, 0)), np.zeros((n, 3, 3))
    fe, e_hg, p_hg, f_old = np.zeros((n, 8, 3)), np.zeros(n), np.zeros(n), np.zeros((n_node, 3))
    zero = np.zeros(n)

    def today_elements():
        hex8.kinematics(x, conn, dN, F, J)
        elastic.evaluate(F, frame, params, state, P, psi, mod)
        hex8.forces(P, dN, w, fe)
        hex8.hourglass(x, v, conn, gamma, k_hg, zero, fe, e_hg, p_hg)

    def today():
        today_elements()
        f_old[:] = 0.0
        gather_add(fe, ptr, slots, f_old)

    nb = -(-n // LANES)
    conn_t = to_blocks(conn, nb)
    ref = np.concatenate([b.reshape(n, 24), V0[:, None], gamma.reshape(n, 32), k_hg[:, None]], axis=1)
    ref_t = to_blocks(ref, nb)
    assert ref_t.shape[1] == REF_ROWS
    fe_t, out_t, f_new = np.zeros((nb, 24, LANES)), np.zeros((nb, 4, LANES)), np.zeros((n_node, 3))
    offsets = block_slots(slots)

    fe_engine, no_fe = np.zeros((nb * LANES, 8, 3)), np.zeros((0, 8, 3))
    f_engine = np.zeros((n_node, 3))

    def blocked():
        fused_blocks(x, conn_t, ref_t, lam, mu, fe_t, out_t, no_fe, args.copy)
        f_new[:] = 0.0
        gather_blocks(fe_t, ptr, offsets, f_new)

    def blocked_engine_layout():
        fused_blocks(x, conn_t, ref_t, lam, mu, fe_t, out_t, fe_engine, args.copy)
        f_engine[:] = 0.0
        gather_add(fe_engine, ptr, slots, f_engine)

    today()
    blocked()
    blocked_engine_layout()
    flat = lambda a: a.transpose(0, 2, 1).reshape(nb * LANES, -1)[:n]  # noqa: E731
    same = {"element forces": np.array_equal(flat(fe_t), fe.reshape(n, 24)),
            "psi": np.array_equal(flat(out_t)[:, 0], psi[:, 0]), "J": np.array_equal(flat(out_t)[:, 1], J[:, 0]),
            "modulus": np.array_equal(flat(out_t)[:, 2], mod[:, 0, 0]),
            "hourglass energy": np.array_equal(flat(out_t)[:, 3], e_hg),
            "nodal forces": np.array_equal(f_new, f_old) and np.array_equal(f_engine, f_old),
            "engine layout": np.array_equal(fe_engine[:n], fe)}
    packed, scalar = packed_and_scalar(fused_blocks)
    print(f"{n} elements, {args.threads} thread(s); block kernel: {packed} packed, {scalar} scalar multiply/add "
          f"instructions; same bits as today's passes: {same}")
    for k in range(args.rounds):
        t_today = best_us_per_element(today, n, calls=50, repeats=5)
        t_block = best_us_per_element(blocked, n, calls=50, repeats=5)
        e_today = best_us_per_element(today_elements, n, calls=50, repeats=5)
        t_engine = best_us_per_element(blocked_engine_layout, n, calls=50, repeats=5)
        e_block = best_us_per_element(
            lambda: fused_blocks(x, conn_t, ref_t, lam, mu, fe_t, out_t, no_fe, args.copy), n, 50, 5)
        print(f"round {k + 1}: today's passes + gather {t_today:.4f} us per element; fused blocks + gather "
              f"{t_block:.4f} us ({t_today / t_block:.2f}x), storing the engine's layout {t_engine:.4f} us "
              f"({t_today / t_engine:.2f}x); element update alone {e_today:.4f} against {e_block:.4f} us "
              f"({e_today / e_block:.2f}x)")
    # the engine's group (hex8.Hex8Group, which takes hex8_blocks for this pairing) with its block path on and off
    from fdeck.deck.model import Hourglass
    from fdeck.registry import MATERIALS

    g = hex8.Hex8Group("s", "reduced", X, conn, np.arange(n), MATERIALS["linear_elastic"], params,
                       np.broadcast_to(np.eye(3), (n, 3, 3)), np.full(n, 7.8e-9), Hourglass())
    engine_blocks = g.blocks
    for k in range(args.rounds):
        g.blocks = engine_blocks
        on = best_us_per_element(lambda: g.update(x, v), n, calls=50, repeats=5)
        g.blocks = None
        off = best_us_per_element(lambda: g.update(x, v), n, calls=50, repeats=5)
        print(f"round {k + 1}: the engine's Hex8Group.update, block path {on:.4f} us per element, the four passes "
              f"{off:.4f} us ({off / on:.2f}x)")


if __name__ == "__main__":
    main()
