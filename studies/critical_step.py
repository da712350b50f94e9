"""Is the run's step above the mesh's critical step? The largest frequency of the whole blank at a checkpoint.

    python studies/critical_step.py DECK CHECKPOINT [--projectors current|reference|saved] [--modes 3]

Restores the engine state of CHECKPOINT (a checkpoint of a run of DECK, read as ``fdeck run --restart`` reads it
but without the build check, so a checkpoint of an earlier fdeck whose state has the same layout is read too) and
computes the eigenvalues lambda of largest magnitude of (M + dM)^-1 K on the free dofs by Arnoldi (scipy's ``eigs``:
F-bar-like elements, ``fbar``, ``ans_fbar``, ``ans_tbar``, have a non-symmetric tangent, so not Lanczos):
K the element groups' tangent at the checkpoint's positions as a matrix-free product, K p = (f(x + h p) -
f(x - h p)) / 2h (central differences of the groups' internal forces, h = 1e-6 mm over max |p|); M + dM the lumped
mass and the selective added mass of the step (``engine.selective_mass``), its inverse by the engine's own
conjugate-gradient solve to 1e-10. Central differences with step dt are stable for a real positive lambda while
lambda dt^2 / 4 <= 1: prints each lambda (its imaginary part too), the critical step 2 / sqrt(Re lambda) against
the step the run was taking, and where the top mode lives (its largest nodes, their reference positions).

``--projectors``: the added mass's rigid modes at the checkpoint's positions (``current``, what the engine does
since 2026-11-29), at the reference positions (``reference``, what it did before), or as the checkpoint saved them
(``saved``). Only the element groups' stiffness is counted: implicit contact springs do not bound the step, but an
explicit effect's stiffness (fibre bending's hinges, explicit contact springs) adds to the elements' in squared
frequencies, so on decks with such effects the critical step printed is an upper bound of the true one. The script
prints K's asymmetry |p^T K q - q^T K p| / sqrt(|p^T K p| |q^T K q|) for two random vectors and how many of the
conjugate-gradient solves reached their cap.

Cost: each Arnoldi iteration is two force evaluations and one solve; on the 66 400-element tetrahedron on
2 threads 55-452 solves, about 4-8 min with compiling (measured 2026-11-29/30). Needs selective mass in the
checkpoint's step (for a lumped mass the element estimate is a bound).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import LinearOperator, eigs

from fdeck.compile.problem import compile_deck
from fdeck.deck.read import read_deck
from fdeck.engine import solver
from fdeck.io.checkpoint import read_checkpoint
from fdeck.run import fit_history


CAP = 5000  # conjugate-gradient iterations per solve


class _Restore(solver.Sink):
    """A sink that keeps the engine state the run hands it when it stops at once."""

    def __init__(self):
        self.state = None

    def frame(self, *args, **kwargs):
        pass

    def history(self, row):
        pass

    def checkpoint_due(self, cycles):
        return False

    def checkpoint(self, state, reason):
        self.state = state()


def restore(deck_path: Path, checkpoint: Path):
    """(problem, engine state) with every object of the problem set to the checkpoint's state."""
    deck, _, _ = read_deck(deck_path)
    problem = compile_deck(deck, deck_path.parent)
    engine = read_checkpoint(checkpoint)["engine"]
    fit_history(engine["result"], solver.history_columns(problem), str(checkpoint))
    sink = _Restore()
    solver.run(problem, sink, should_stop=lambda: True, resume=engine)
    return problem, sink.state


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("deck", type=Path)
    ap.add_argument("checkpoint", type=Path)
    ap.add_argument("--projectors", choices=("current", "reference", "saved"), default="current")
    ap.add_argument("--modes", type=int, default=3)
    args = ap.parse_args(argv)
    problem, state = restore(args.deck, args.checkpoint)
    x = state["arrays"]["x"].copy()
    dt_run = state["scalars"]["dt_next"]
    effect = next((e for e in problem.effects if getattr(e, "solves_mass", False)), None)
    if effect is None or not effect.solver.active:
        raise SystemExit("the checkpoint's step has no selective mass: the elements' own step estimates bound it")
    s = effect.solver
    zero = np.zeros_like(x)
    if args.projectors == "current":
        s.follow(x, zero)
    elif args.projectors == "reference":
        s.follow(problem.X, zero)
    free = s.free > 0.0
    n = len(x)
    f = np.zeros((n, 3))

    def internal(y):
        f.fill(0.0)
        for g in problem.groups:
            g.update(y, zero)
            g.add_forces(f)
        return f.copy()

    def full(p):
        out = np.zeros((n, 3))
        out[free] = p
        return out

    def stiffness(p):
        q = full(p)
        h = 1e-6 / max(np.abs(q).max(), 1e-300)
        return ((internal(x + h * q) - internal(x - h * q)) / (2.0 * h))[free]

    capped = []

    def inverse(r):
        a = np.zeros((n, 3))
        capped.append(s.solve_mass(a, full(r), 1e-10, CAP) >= CAP)
        return a[free]

    size = int(free.sum())
    rng = np.random.default_rng(1)
    p, q = rng.standard_normal(size), rng.standard_normal(size)
    Kp, Kq = stiffness(p), stiffness(q)
    asym = abs(p @ Kq - q @ Kp) / np.sqrt(abs(p @ Kp) * abs(q @ Kq))
    op = LinearOperator((size, size), matvec=lambda p: inverse(stiffness(p)), dtype=float)
    lam, vec = eigs(op, k=args.modes, which="LM", tol=1e-6)
    order = np.argsort(-np.abs(lam))
    print(f"{args.checkpoint} (t = {state['scalars']['t']:.6g} s), rigid modes of the added mass: {args.projectors}")
    print(f"step the run was taking: {dt_run:.4g} s; K's asymmetry {asym:.1e}; "
          f"{len(capped)} solves, {sum(capped)} at the cap of {CAP} iterations")
    for i in order:
        re, im = lam[i].real, lam[i].imag
        ratio = re * dt_run ** 2 / 4.0
        print(f"  lambda {re:.6e} {im:+.1e}i 1/s^2 -> critical step {2.0 / np.sqrt(re):.4g} s "
              f"(lambda dt^2 / 4 = {ratio:.3f}: {'unstable' if ratio > 1.0 else 'stable'})")
    u = full(vec[:, order[0]].real)
    amp = np.linalg.norm(u, axis=1)
    top = np.argsort(amp)[::-1][:8]
    share = float((amp[top] ** 2).sum() / (amp ** 2).sum())
    print(f"top mode: {100 * share:.0f} % of its squared amplitude on 8 nodes; nodes (reference position [mm]):")
    for i in top:
        print(f"  {i}: {np.round(problem.X[i], 2).tolist()}")
    # the elements there: their own step estimates (at the checkpoint's moduli and densities) and added mass
    offset = 0
    for g in problem.groups:
        g.update(x, zero)
        g.stable_dt()
        near = np.flatnonzero(np.isin(g.conn, top).any(axis=1))
        if len(near):
            unit = g.mass(np.ones(len(g.conn))).sum(axis=1)[near] / g.conn.shape[1]  # per unit density [mm^3]
            base = effect.plan.translational(problem.groups.index(g))[near] * unit  # m_e / n [t]
            beta = s.c[offset + near] / base
            print(f"  group {g.name}: {len(near)} elements on those nodes, their step estimates "
                  f"{g.dt_e[near].min():.3g}..{g.dt_e[near].max():.3g} s, added mass {beta.min():.3g}..{beta.max():.3g}"
                  f" x their translational mass")
        offset += len(g.conn)


if __name__ == "__main__":
    main()
