"""Can numba vectorise element-batched kernels here? A probe for issue 10's SIMD route (not part of the tests).

    python benchmarks/simd_probe.py                        # numba's default: LLVM's SLP vectoriser off
    NUMBA_SLP_VECTORIZE=1 NUMBA_CACHE_DIR=/tmp/slp python benchmarks/simd_probe.py

1. A lane loop ``out[b, l] += x[b, a, l] * g[b, a, l]`` (elements b in blocks of L lanes, nodes a): counts the
   packed (``vmulpd``/``vaddpd``) and scalar double instructions in its assembly for L = 4, 8, 16, 64. fdeck compiles
   without fastmath, and numba 0.57+ ships with LLVM's SLP vectoriser off (numba PR 8852, miscompilations), so a
   short constant lane loop is unrolled and left scalar; only the loop vectoriser remains, for long trip counts.
2. The hexahedron's hourglass forces (stiffness type) as today (one element at a time) and in blocks of 64
   elements with the lanes innermost (conn, gamma and the forces transposed per block): time per element (best of
   7 x 50 calls, one thread, 12 800 elements) and whether the two give the same bits (forces and stored energy;
   the probe's blocked version has the stiffness type only).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numba
import numpy as np
from numba import njit, prange

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fdeck.compile.mesh import block  # noqa: E402
from kernel_parts import best_us_per_element  # noqa: E402
from fdeck.physics.elements import hex8  # noqa: E402

FLAGS = dict(boundscheck=False, error_model="numpy", fastmath=False)


def _lane_kernel(lanes: int):
    @njit(**FLAGS)
    def lane_loop(x, g, out):
        for b in range(out.shape[0]):
            for a in range(8):
                for l in range(lanes):
                    out[b, l] += x[b, a, l] * g[b, a, l]
    return lane_loop


def packed_and_scalar(fn) -> tuple[int, int]:
    """Packed and scalar double multiply/add instructions in the assembly of fn's first signature."""
    asm = fn.inspect_asm(fn.signatures[0])
    return asm.count("vmulpd") + asm.count("vaddpd"), asm.count("vmulsd") + asm.count("vaddsd")


@njit(parallel=True, **FLAGS)
def hourglass_blocks(x, conn_t, gamma_t, k, fe_t, e_hg, lanes):
    """Stiffness hourglass forces per block of ``lanes`` elements: conn_t (nb, 8, lanes), gamma_t (nb, 4, 8,
    lanes), k (nb, lanes), fe_t (nb, 8, 3, lanes) added to, e_hg (nb, lanes); each sum in hex8.hourglass's order."""
    for b in prange(conn_t.shape[0]):
        q = np.zeros((12, lanes))
        y = np.empty((3, lanes))
        for a in range(8):
            for l in range(lanes):
                n = conn_t[b, a, l]
                y[0, l] = x[n, 0]
                y[1, l] = x[n, 1]
                y[2, l] = x[n, 2]
            for m in range(4):
                for c in range(3):
                    for l in range(lanes):
                        q[3 * m + c, l] += y[c, l] * gamma_t[b, m, a, l]
        for l in range(lanes):
            e_hg[b, l] = 0.0
        for i in range(12):
            for l in range(lanes):
                e_hg[b, l] += 0.5 * k[b, l] * q[i, l] * q[i, l]
                q[i, l] = k[b, l] * q[i, l]
        for a in range(8):
            for c in range(3):
                for l in range(lanes):
                    f = fe_t[b, a, c, l]
                    f += q[c, l] * gamma_t[b, 0, a, l]
                    f += q[3 + c, l] * gamma_t[b, 1, a, l]
                    f += q[6 + c, l] * gamma_t[b, 2, a, l]
                    f += q[9 + c, l] * gamma_t[b, 3, a, l]
                    fe_t[b, a, c, l] = f


def main() -> None:
    numba.set_num_threads(1)
    print(f"numba {numba.__version__}, SLP vectoriser {'on' if numba.config.SLP_VECTORIZE else 'off'}")
    for lanes in (4, 8, 16, 64):
        fn = _lane_kernel(lanes)
        fn(np.ones((10, 8, lanes)), np.ones((10, 8, lanes)), np.zeros((10, lanes)))
        packed, scalar = packed_and_scalar(fn)
        print(f"lane loop, {lanes:2d} lanes: {packed} packed, {scalar} scalar multiply/add instructions")
    lanes = 64
    mesh = block([0, 0, 0], [64, 50, 4], divisions=[64, 50, 4])
    X, conn = mesh.X, np.ascontiguousarray(mesh.cells["hexahedron"], np.int64)
    gamma = hex8.prepare(X, conn)["gamma"]
    rng = np.random.default_rng(3)
    x = X + 0.01 * rng.normal(size=X.shape)
    n = len(conn)
    nb = n // lanes
    k = rng.uniform(0.5, 1.0, n)
    fe, e_hg, p_hg = np.zeros((n, 8, 3)), np.zeros(n), np.zeros(n)
    args = (x, np.zeros_like(x), conn, gamma, k, np.zeros(n), fe, e_hg, p_hg)
    conn_t = np.ascontiguousarray(conn.reshape(nb, lanes, 8).transpose(0, 2, 1))
    gamma_t = np.ascontiguousarray(gamma.reshape(nb, lanes, 4, 8).transpose(0, 2, 3, 1))
    fe_t, e_t = np.zeros((nb, 8, 3, lanes)), np.zeros((nb, lanes))
    args_t = (x, conn_t, gamma_t, np.ascontiguousarray(k.reshape(nb, lanes)), fe_t, e_t, lanes)
    for _ in range(2):
        one = best_us_per_element(lambda: hex8.hourglass(*args), n, calls=50, repeats=7)
        blocked = best_us_per_element(lambda: hourglass_blocks(*args_t), n, calls=50, repeats=7)
        print(f"hourglass, {n} elements, 1 thread: one element at a time {one:.4f} us, "
              f"blocks of {lanes} {blocked:.4f} us per element")
    fe[:] = 0.0
    fe_t[:] = 0.0
    hex8.hourglass(*args)
    hourglass_blocks(*args_t)
    same = np.array_equal(fe_t.transpose(0, 3, 1, 2).reshape(n, 8, 3), fe) and np.array_equal(e_t.ravel(), e_hg)
    packed, scalar = packed_and_scalar(hourglass_blocks)
    print(f"blocks: same bits as one at a time: {same}; {packed} packed, {scalar} scalar multiply/add instructions")


if __name__ == "__main__":
    main()
