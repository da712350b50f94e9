"""Where one explicit cycle of a hexahedral block goes, kernel by kernel (not part of the test suite).

    python benchmarks/kernel_parts.py reduced linear_elastic             # 50 x 50 x 4 block, 1 thread
    python benchmarks/kernel_parts.py fbar fabric_hyper_3weave --threads 2

Builds bench.py's block deck, deforms it by a fixed pseudo-random 1 % of an element, then times each kernel of the
element update (kinematics, law, forces, hourglass), the deterministic gather, the stable step and the two integrator
passes on their own, each the best of five repeats of 100 calls, in microseconds per element and call; then the
whole cycle as ``solver.run`` measures it (200 cycles after a warm-up, with the solver's own split). The parts'
sum and the whole differ by the solver's bookkeeping. Run it at two commits (``git worktree``) to see what a change
to a kernel bought; on a shared host, run both back to back and read the differences, not the absolute values.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))


def best_us_per_element(fn, n_el: int, calls: int = 100, repeats: int = 5) -> float:
    """Best over ``repeats`` of the mean time of ``calls`` calls of fn(), per element [us]."""
    fn()
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(calls):
            fn()
        best = min(best, (time.perf_counter() - t0) / calls)
    return 1e6 * best / n_el


def parts(form: str, mat: str, divisions, threads: int) -> dict:
    """{kernel: us per element and call} for one hexahedral group, and the whole cycle under ``whole``."""
    import numba
    import numpy as np

    import bench
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import integrate, solver
    from fdeck.engine.gather import gather_add
    from fdeck.physics.elements import hex8

    numba.set_num_threads(threads)
    problem = compile_deck(Deck.model_validate(bench.deck(form, mat, divisions, 200)))
    g = problem.groups[0]
    n = len(g.conn)
    rng = np.random.default_rng(0)
    x = problem.X + 0.01 * rng.standard_normal(problem.X.shape)  # elements are 1 mm: a 1 % generic distortion
    v = rng.standard_normal(problem.X.shape)
    f = np.zeros_like(x)
    m = g.material
    out = {}
    if form == "fbar":
        out["kinematics_fbar"] = lambda: hex8.kinematics_fbar(x, g.conn, g.dN, g.w, g.F, g.J, g.Fbar, g.Jbar,
                                                              g.ratio)
        out["law"] = lambda: m.evaluate(g.Fbar, g.frame, g.params, g.state, g.P, g.psi, g.modulus)
        out["forces_fbar"] = lambda: hex8.forces_fbar(g.F, g.J, g.Jbar, g.ratio, g.P, g.dN, g.w, g.p, g.fe)
    else:
        out["kinematics"] = lambda: hex8.kinematics(x, g.conn, g.dN, g.F, g.J)
        out["law"] = lambda: m.evaluate(g.F, g.frame, g.params, g.state, g.P, g.psi, g.modulus)
        out["forces"] = lambda: hex8.forces(g.P, g.dN, g.w, g.fe)
    if g.has_hourglass:
        out["hourglass"] = lambda: hex8.hourglass(x, v, g.conn, g.gamma, g.k_hg, g.c_hg, g.fe, g.e_hg, g.p_hg)
    out["gather"] = lambda: gather_add(g.fe, g.ptr, g.slots, f)
    out["stable_step"] = g.stable_dt
    v_old, inv_m, zero = v.copy(), np.ones(len(x)), np.zeros_like(x)
    work = [np.zeros_like(x) for _ in range(4)]
    out["kick"] = lambda: integrate.kick(v, v_old, inv_m, zero, f, zero, 1e-9)
    out["drift"] = lambda: integrate.drift(x, v, v_old, inv_m, zero, f, zero, *work, 0.0, 1e-9, False)
    result = {name: best_us_per_element(fn, n) for name, fn in out.items()}
    problem.steps[0].max_cycles = 3
    solver.run(problem, solver.Sink())
    problem.steps[0].max_cycles = 200
    t0 = time.perf_counter()
    res = solver.run(problem, solver.Sink())
    scale = 1e6 / (res.cycles * n)
    result["whole"] = (time.perf_counter() - t0) * scale
    result["solver_split"] = {k: round(s * scale, 4) for k, s in res.timings.items() if s > 0}
    return result


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("formulation", choices=["reduced", "full", "fbar"])
    ap.add_argument("material", help="bench.py's material names: linear_elastic, neo_hookean, fabric_hyper_3weave")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--divisions", type=int, nargs=3, default=[50, 50, 4])
    a = ap.parse_args()
    r = parts(a.formulation, a.material, a.divisions, a.threads)
    split = r.pop("solver_split")
    whole = r.pop("whole")
    for name, us in r.items():
        print(f"{name:16s} {us:8.4f} us per element")
    print(f"{'sum of parts':16s} {sum(r.values()):8.4f}")
    print(f"{'whole cycle':16s} {whole:8.4f}  (solver's split: {split})")


if __name__ == "__main__":
    main()
