"""Does fusing the reduced hexahedron's passes into one element loop pay? A probe for issue 10 (not part of the tests).

    python benchmarks/fusion_probe.py                  # 50 x 50 x 4 (10 000 elements, in cache) and 160 x 160 x 4
    python benchmarks/fusion_probe.py --threads 2

Today ``Hex8Group.update`` runs the kinematics (F, J), the law (P, psi, moduli), the nodal forces and the hourglass
forces as four passes over the elements, each storing what the next one reads. The probe writes the same four steps
for the ``reduced`` formulation with linear elasticity as one ``prange`` loop over the elements (each element's F, P
and forces used while still in L1), checks that it gives the same bits as the passes (element forces, stresses,
energies), and times both (best of 5 x 100 calls, microseconds per element, the two interleaved over 3 rounds) on a
cache-resident block (10 000 elements) and a DRAM-resident one (102 400). docs/kernels.md, item 7, gives the
answer and what it means for the route to the floor.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numba
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench  # noqa: E402
from fdeck.compile.problem import compile_deck  # noqa: E402
from fdeck.deck.model import Deck  # noqa: E402
from fdeck.jit import njit_parallel, prange  # noqa: E402
from fdeck.physics.elements.hex8 import _deformation_gradients, _nodal_forces, hourglass_element  # noqa: E402
from fdeck.physics.materials import elastic  # noqa: E402
from kernel_parts import best_us_per_element  # noqa: E402


@njit_parallel
def fused(x, v, conn, dN, w, F, J, frame, params, state, P, psi, modulus, fe, gamma, k_hg, c_hg, e_hg, p_hg):
    """``Hex8Group.update`` of a reduced linear elastic group with hourglass control, in one element loop (the same
    helpers and arithmetic in the same order as kinematics, evaluate, forces and hourglass)."""
    for e in prange(conn.shape[0]):
        _deformation_gradients(x, conn, dN, F, J, e)
        psi[e, 0], modulus[e, 0, 0], modulus[e, 0, 1], modulus[e, 0, 2] = elastic.point(
            F[e, 0], frame[e], params[e], state[e, 0], P[e, 0])
        _nodal_forces(P, dN, w, fe, e)
        hourglass_element(x, v, conn, gamma, k_hg, c_hg, fe, e_hg, p_hg, e)


def probe(divisions, rounds: int) -> dict:
    problem = compile_deck(Deck.model_validate(bench.deck("reduced", "linear_elastic", divisions, 200)))
    g = problem.groups[0]
    n = len(g.conn)
    rng = np.random.default_rng(0)
    x = problem.X + 0.01 * rng.standard_normal(problem.X.shape)  # 1 mm elements: a 1 % generic distortion
    v = rng.standard_normal(problem.X.shape)

    def passes():
        g.update(x, v)

    def one_loop():
        fused(x, v, g.conn, g.dN, g.w, g.F, g.J, g.frame, g.params, g.state, g.P, g.psi, g.modulus, g.fe, g.gamma,
              g.k_hg, g.c_hg, g.e_hg, g.p_hg)

    passes()
    ref = [a.copy() for a in (g.fe, g.P, g.psi, g.e_hg)]
    for a in (g.fe, g.P, g.psi, g.e_hg):  # so that "same bits" cannot pass on what the passes left there
        a[...] = np.nan
    one_loop()
    same = all(np.array_equal(a, b) for a, b in zip(ref, (g.fe, g.P, g.psi, g.e_hg)))
    times = {"passes": [], "one loop": []}
    for _ in range(rounds):
        times["passes"].append(best_us_per_element(passes, n))
        times["one loop"].append(best_us_per_element(one_loop, n))
    return {"elements": n, "same bits": same, **{k: (min(t), max(t)) for k, t in times.items()}}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    numba.set_num_threads(args.threads)
    for divisions in ((50, 50, 4), (160, 160, 4)):
        r = probe(divisions, args.rounds)
        print(f"{r['elements']} elements, {args.threads} thread(s), same bits: {r['same bits']}; us per element "
              f"(min-max of {args.rounds} rounds): passes {r['passes'][0]:.4f}-{r['passes'][1]:.4f}, one loop "
              f"{r['one loop'][0]:.4f}-{r['one loop'][1]:.4f}")


if __name__ == "__main__":
    main()
