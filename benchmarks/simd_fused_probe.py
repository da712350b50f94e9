"""The reduced hexahedron with linear elasticity fused and vectorised over blocks of elements (issue 10's SIMD
route; a probe, not part of the engine or the tests).

    python benchmarks/simd_fused_probe.py                  # 10 000 elements, 1 thread, 3 rounds
    python benchmarks/simd_fused_probe.py --size 102400 --threads 2
    python benchmarks/simd_fused_probe.py --size 102400 --copy  # each block's reference data copied linearly first

Today's general path runs the element update as four passes over the elements, one element at a time
(kinematics, the law, forces, hourglass: ``hex8`` and ``elastic``), then the deterministic gather into the nodes.
``physics/elements/hex8_blocks.py`` runs the same arithmetic once per block of 64 elements, lanes innermost, in
lane loops over one work array per block, and gives the same bits; the engine takes it for ``reduced`` with
``linear_elastic``. This probe times three things on the same deformed block (stiffness hourglass):

* today's four passes + ``gather_add``;
* the bare block kernel (``hex8_blocks``' lane loops, the forces left in the block layout, nothing else stored)
  + a gather that reads the block layout (a node's three components in three cache lines); with ``--copy`` each
  block's reference chunk is first copied linearly into a local array (one stream for the prefetchers);
* the engine's ``Hex8Group.update`` with its block path on and off.

What it showed (docs/kernels.md, item 8): numba vectorises a lane loop (no fastmath, SLP vectoriser off:
``simd_probe.py``) only while the arrays it writes and reads are few: F + law writing two output arrays and reading
three vectorised, writing three did not (consistent with LLVM's limit on runtime alias checks, 8 pointer pairs by
default); with one work array per block (rows at constant offsets) and one reference array, it does. The forces
and hourglass forces vectorise best as 1-D row views with the lanes innermost.

Prints the packed and scalar double multiply/add instructions of the bare kernel (none when numba loads it from its
cache), the same-bits check, and per round the times per element.
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
from fdeck.physics.elements import hex8, hex8_blocks  # noqa: E402
from fdeck.physics.materials import elastic  # noqa: E402
from kernel_parts import best_us_per_element  # noqa: E402
from simd_probe import packed_and_scalar  # noqa: E402

LANES = hex8_blocks.LANES


@numba.njit(parallel=True, **FLAGS)
def bare_blocks(x, conn_t, ref_t, lam, mu, fe_t, copy):
    """The lane loops of ``hex8_blocks`` (stiffness hourglass) with the element forces left in the block layout
    fe_t (n_block, 24, LANES), rows 3 a + i, and nothing else stored (the engine's kernel, ``update_blocks``, also
    stores F, P, J, psi, moduli and energies in the engine's arrays). With copy, each block's reference chunk is
    first copied linearly into a local array (one stream for the prefetchers)."""
    for blk in numba.prange(conn_t.shape[0]):
        w = np.empty((hex8_blocks.WORK_ROWS, LANES))
        r = ref_t[blk]
        if copy:
            r = np.empty((hex8_blocks.REF_ROWS, LANES))
            for k in range(hex8_blocks.REF_ROWS):
                for l in range(LANES):
                    r[k, l] = ref_t[blk, k, l]
        for a in range(8):
            for l in range(LANES):
                n = conn_t[blk, a, l]
                w[hex8_blocks.X_ROW + 3 * a, l] = x[n, 0]
                w[hex8_blocks.X_ROW + 3 * a + 1, l] = x[n, 1]
                w[hex8_blocks.X_ROW + 3 * a + 2, l] = x[n, 2]
        f = fe_t[blk]
        hex8_blocks._kinematics_and_law(w, r, lam, mu)
        hex8_blocks._forces(w, r, f)
        hex8_blocks._hourglass(w, r, f, True, False, False)


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
    blocks = hex8_blocks.Blocks(conn, b, V0, gamma, k_hg, zero, params)
    fe_t, f_new = np.zeros((nb, 24, LANES)), np.zeros((n_node, 3))
    offsets = block_slots(slots)

    def bare():
        bare_blocks(x, blocks.conn_t, blocks.ref_t, lam, mu, fe_t, args.copy)
        f_new[:] = 0.0
        gather_blocks(fe_t, ptr, offsets, f_new)

    today()
    bare()
    flat = fe_t.transpose(0, 2, 1).reshape(nb * LANES, 24)[:n]
    same = {"element forces": np.array_equal(flat, fe.reshape(n, 24)), "nodal forces": np.array_equal(f_new, f_old)}
    packed, scalar = packed_and_scalar(bare_blocks)
    print(f"{n} elements, {args.threads} thread(s); bare block kernel: {packed} packed, {scalar} scalar multiply/add "
          f"instructions; same bits as today's passes: {same}")
    for k in range(args.rounds):
        t_today = best_us_per_element(today, n, calls=50, repeats=5)
        t_bare = best_us_per_element(bare, n, calls=50, repeats=5)
        e_today = best_us_per_element(today_elements, n, calls=50, repeats=5)
        e_bare = best_us_per_element(lambda: bare_blocks(x, blocks.conn_t, blocks.ref_t, lam, mu, fe_t, args.copy),
                                     n, 50, 5)
        print(f"round {k + 1}: today's passes + gather {t_today:.4f} us per element; bare blocks + their gather "
              f"{t_bare:.4f} us ({t_today / t_bare:.2f}x); element update alone {e_today:.4f} against {e_bare:.4f} "
              f"us ({e_today / e_bare:.2f}x)")
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
