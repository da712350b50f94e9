"""Where one explicit cycle of a hexahedral block goes, kernel by kernel (not part of the suite).

    python benchmarks/kernel_parts.py reduced linear_elastic             # 50 x 50 x 4 block, 1 thread
    python benchmarks/kernel_parts.py fbar fabric_hyper_3weave --threads 2
    python benchmarks/kernel_parts.py fbar fabric_hyper_3weave --selective 30   # and the selective-mass solve

Builds bench.py's block deck, deforms it by a fixed pseudo-random 1 % of an element, then times each kernel of the
element update (kinematics, law, forces, hourglass), the deterministic gather, the stable step and the two integrator
passes on their own, each the best of five repeats of 100 calls, in microseconds per element and call; then the
whole cycle as ``solver.run`` measures it (200 cycles after a warm-up, with the solver's own split). The parts'
sum and the whole differ by the solver's bookkeeping. With ``--selective FACTOR`` the step is selectively mass
scaled by that factor and the conjugate-gradient solve's passes are timed too (``cg_*``, per element and pass;
``cg_solve_per_iteration``: one whole solve from zero of the cycle's residual, per element and iteration).
With ``--count`` it counts each pass's operations per element instead (``floor.py``'s counting floats, one
element deformed by 3 %, the kernels' scratch arrays counting too).
Run it at two commits (``git worktree``) to see what a change to a kernel bought; on a shared host, run both back
to back and read the differences, not the absolute values.
"""

from __future__ import annotations

import argparse
import os
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


def parts(form: str, mat: str, divisions, threads: int, selective: float | None = None) -> dict:
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
    card = bench.deck(form, mat, divisions, 200)
    if selective:
        card["steps"][0]["mass_scaling"] = {"factor": selective, "selective": True}
    problem = compile_deck(Deck.model_validate(card))
    g = problem.groups[0]
    n = len(g.conn)
    rng = np.random.default_rng(0)
    x = problem.X + 0.01 * rng.standard_normal(problem.X.shape)  # elements are 1 mm: a 1 % generic distortion
    v = rng.standard_normal(problem.X.shape)
    f = np.zeros_like(x)
    out = element_passes(form, g, x, v)
    out["gather"] = lambda: gather_add(g.fe, g.ptr, g.slots, f)
    out["stable_step"] = g.stable_dt
    v_old, inv_m, zero = v.copy(), np.ones(len(x)), np.zeros_like(x)
    work = [np.zeros_like(x) for _ in range(4)]
    out["kick"] = lambda: integrate.kick(v, v_old, inv_m, zero, f, zero, 1e-9)
    out["drift"] = lambda: integrate.drift(x, v, v_old, inv_m, zero, f, zero, *work, 0.0, 1e-9, False)
    if selective:
        sms = _solver_of(problem)
        out.update(cg_parts(sms, x))
    result = {name: best_us_per_element(fn, n) for name, fn in out.items()}
    if selective:
        result["cg_solve_per_iteration"] = cg_solve_per_iteration(sms, g, x)
    problem.steps[0].max_cycles = 3
    solver.run(problem, solver.Sink())
    problem.steps[0].max_cycles = 200
    t0 = time.perf_counter()
    res = solver.run(problem, solver.Sink())
    scale = 1e6 / (res.cycles * n)
    result["whole"] = (time.perf_counter() - t0) * scale
    result["solver_split"] = {k: round(s * scale, 4) for k, s in res.timings.items() if s > 0}
    return result


def element_passes(form: str, g, x, v) -> dict:
    """{pass name: callable} of one hexahedral group's element update at positions x, velocities v (n_node, 3)."""
    from fdeck.physics.elements import hex8

    m = g.material
    out = {}
    if form == "fbar":
        out["kinematics_fbar"] = lambda: hex8.kinematics_fbar(x, g.conn, g.dN, g.w, g.F, g.J, g.Fbar, g.Jbar,
                                                              g.ratio)
        out["law"] = lambda: m.evaluate(g.Fbar, g.frame, g.params, g.state, g.P, g.psi, g.modulus)
        out["forces_fbar"] = lambda: hex8.forces_fbar(g.F, g.J, g.Jbar, g.ratio, g.P, g.dN, g.w, g.p, g.fe)
    elif form == "ans_tbar":
        out.update(_ans_tbar_parts(g, x))
    else:
        out["kinematics"] = lambda: hex8.kinematics(x, g.conn, g.dN, g.F, g.J)
        out["law"] = lambda: m.evaluate(g.F, g.frame, g.params, g.state, g.P, g.psi, g.modulus)
        out["forces"] = lambda: hex8.forces(g.P, g.dN, g.w, g.fe)
    if g.has_hourglass:
        out["hourglass"] = lambda: hex8.hourglass(x, v, g.conn, g.gamma, g.k_hg, g.c_hg, g.fe, g.e_hg, g.p_hg)
    return out


def count_passes(form: str, mat: str) -> dict:
    """Operations per element of each element pass, on one element deformed by a fixed pseudo-random 3 %, with
    ``floor.py``'s counting floats; the kernels' local scratch arrays are made counting arrays too (numpy's empty
    and zeros replaced in the element modules). Needs NUMBA_DISABLE_JIT=1."""
    import numba
    import numpy as np

    import bench
    import floor
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.physics.elements import hex8, hex8_ans, hex8_ans_fbar

    class CountingNumpy:
        def __getattr__(self, name):
            return getattr(np, name)

        def empty(self, shape, dtype=float):
            return floor._counted(np.zeros(shape)) if np.dtype(dtype) == np.float64 else np.empty(shape, dtype)

        zeros = empty

    assert numba.config.DISABLE_JIT, "count_passes needs NUMBA_DISABLE_JIT=1 (and leaves numpy patched: one process)"
    floor._patch_math()
    problem = compile_deck(Deck.model_validate(bench.deck(form, mat, (1, 1, 1), 1)))
    (g,) = problem.groups
    for module in (hex8, hex8_ans, hex8_ans_fbar):  # after the set-up, which needs real arrays
        module.np = CountingNumpy()
    for name, a in list(vars(g).items()):
        if isinstance(a, np.ndarray) and a.dtype == np.float64:
            setattr(g, name, floor._counted(np.array(a)))
    if hasattr(g, "ans"):
        g.ans = {k: floor._counted(np.array(a)) for k, a in g.ans.items()}
    rng = np.random.default_rng(1)
    x = floor._counted(problem.X + 0.03 * rng.uniform(-1.0, 1.0, problem.X.shape))
    v = floor._counted(rng.uniform(-1.0, 1.0, problem.X.shape))
    return {name: floor._count(fn) for name, fn in element_passes(form, g, x, v).items()}


def _ans_tbar_parts(g, x) -> dict:
    """The six passes of an ``ans_tbar`` group's update (``hex8_ans_fbar.Hex8AnsTbarGroup.update``) as callables."""
    from fdeck.physics.elements import hex8_ans as ha
    from fdeck.physics.elements import hex8_ans_fbar as hf

    a, m = g.ans, g.material
    return {
        "kinematics_ans": lambda: ha.kinematics_ans(x, g.conn, g.b, g.dN, g.w, a["dxi_s"], a["index"], a["Jinv"],
                                                    a["Gq"], a["Gs"], g.F, g.J, g.Fans, g.F0, g.gs),
        "tbar_on_ans": lambda: hf.tbar_on_ans(g.w, g.F, g.Fans, g.frame, g.T, g.Tbar, g.ratio, g.F_material),
        "law": lambda: m.evaluate(g.F_material, g.frame, g.params, g.state, g.P, g.psi, g.modulus),
        "stress_ans_tbar": lambda: hf.stress_ans_tbar(g.Fans, g.frame, g.T, g.Tbar, g.ratio, g.F_material, g.P,
                                                      g.w, g.p, g.Peff, g.bT),
        "forces_ans": lambda: ha.forces_ans(g.F, g.Fans, g.Peff, g.dN, g.w, g.b, a["dxi_s"], a["index"], a["Jinv"],
                                            a["Gq"], a["Gs"], g.F0, g.gs, g.fe),
        "add_thickness_forces": lambda: hf.add_thickness_forces(g.F, g.frame, g.T, g.bT, g.dN, g.w, g.fe),
    }


def _solver_of(problem):
    """The selective-mass solver of a compiled problem, set up for its first step."""
    from fdeck.engine import solver

    problem.steps[0].max_cycles = 1
    solver.run(problem, solver.Sink())  # begin_step and prepare: the step's factors and preconditioner
    return next(e for e in problem.effects if getattr(e, "solves_mass", False)).solver


def cg_parts(s, x) -> dict:
    """The four passes of one conjugate-gradient iteration (``engine.selective_mass.solve``) of the solver s as
    callables, on nodal arrays shaped as x."""
    import numpy as np

    from fdeck.engine import selective_mass as sm

    rng = np.random.default_rng(1)
    p, res = rng.standard_normal(x.shape), rng.standard_normal(x.shape)
    q, z, a = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
    rows = np.zeros((len(s.conn), sm.ROW))
    return {
        "cg_element_rows": lambda: sm.element_rows(p, s.conn, s.X, s.Xc, s.Jinv, s.c, rows),
        "cg_gather_dot": lambda: sm._gather_dot(rows, s.ptr, s.elems, s.X, q, p, s.free, s._part),
        "cg_direction": lambda: sm._direction(z, res, s.dinv, p, 0.5, q, s.m),
        "cg_step": lambda: sm._step(a, res, p, q, s.free, 0.0, s.dinv, s._part),
    }


def cg_solve_per_iteration(s, g, x) -> float:
    """Best of three whole solves by the solver s from zero of r = -f_int(x) of group g, per element and iteration
    [us]."""
    import numpy as np

    from fdeck.engine import selective_mass as sm

    g.update(x, np.zeros_like(x))
    r = np.zeros_like(x)
    g.add_forces(r)
    r = -r
    work = [np.zeros((len(s.conn), sm.ROW))] + [np.zeros_like(x) for _ in range(4)]
    best = float("inf")
    for _ in range(3):
        a = np.zeros_like(x)
        t0 = time.perf_counter()
        it, _ = sm.solve(a, r, s.m, s.conn, s.X, s.Xc, s.Jinv, s.c, s.ptr, s.elems, s.free, s.dinv, s.tol, s.max_it,
                         *work, s._part, *s._no_springs[:2], 0.0)
        best = min(best, (time.perf_counter() - t0) / max(it, 1))
    return 1e6 * best / len(s.conn)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("formulation", choices=["reduced", "full", "fbar", "ans_tbar"])
    ap.add_argument("material", help="bench.py's material names: linear_elastic, neo_hookean, fabric_hyper_3weave")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--divisions", type=int, nargs=3, default=[50, 50, 4])
    ap.add_argument("--selective", type=float, default=None, metavar="FACTOR",
                    help="selective mass scaling by FACTOR, and time the conjugate-gradient passes")
    ap.add_argument("--count", action="store_true",
                    help="count each pass's operations per element instead (floor.py's counter; no timing)")
    a = ap.parse_args()
    if a.count:
        if os.environ.get("NUMBA_DISABLE_JIT") != "1":  # the counter needs the pure-Python kernels
            os.execve(sys.executable, [sys.executable, *sys.argv], dict(os.environ, NUMBA_DISABLE_JIT="1"))
        for name, c in count_passes(a.formulation, a.material).items():
            ops = ", ".join(f"{k} {n:.0f}" for k, n in c.items())
            print(f"{name:24s} {sum(c.values()):8.0f} flops per element ({ops})")
        return
    r = parts(a.formulation, a.material, a.divisions, a.threads, a.selective)
    split = r.pop("solver_split")
    whole = r.pop("whole")
    for name, us in r.items():
        print(f"{name:24s} {us:8.4f} us per element")
    print(f"{'sum of parts':24s} {sum(us for k, us in r.items() if not k.startswith('cg_')):8.4f} (cg_ aside)")
    print(f"{'whole cycle':24s} {whole:8.4f}  (solver's split: {split})")
    if a.formulation == "reduced" and a.material == "linear_elastic":
        print("(reduced + linear_elastic: the engine's whole cycle runs hex8_blocks, the fused block path; the parts "
              "above are the general path's four passes: benchmarks/simd_fused_probe.py compares the two)")


if __name__ == "__main__":
    main()
