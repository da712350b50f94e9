"""Would a stronger preconditioner cut the selective-mass solve's iterations? (a probe, not part of the test suite)

    python benchmarks/cg_preconditioners.py DECK CHECKPOINT [--tol 1e-3]

Takes the added mass of a run at a checkpoint (its factors c_e, lumped masses, free dofs and the last three cycles'
accelerations) on the deck's mesh, assembles M + dM on the free dofs as a sparse matrix (scipy), and counts the
preconditioned conjugate-gradient iterations to the engine's stopping rule (``engine.selective_mass.solve``) for the
system the engine solved at that cycle (right-hand side (M + dM) a), from zero and from the linear extrapolation of
the two cycles before, with:

* the assembled diagonal (Jacobi; the engine's sums the slots' diagonals, which differs at prisms' repeated nodes);
* two-level, additive (D^-1 + P A_c^-1 P^T) and as a symmetric V-cycle (damped Jacobi, coarse solve, damped Jacobi:
  three products per iteration), with a coarse space on aggregates of nodes (each node and its neighbours, greedy),
  of translations only or of the six rigid modes, plain or smoothed once (smoothed aggregation);
* the six rigid modes of each connected cluster of heavy elements (c_e above a multiple of its nodes' mean mass),
  additive: the lowest modes of D^-1 (M + dM) sit at such clusters.

Coarse systems are factorised exactly (scipy's splu), so the counts are what each coarse space could give at best.
Prints one line per preconditioner and the extreme eigenvalues of D^-1 (M + dM).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def saved_solver(payload) -> dict:
    """The arrays of the selective-mass solver in a checkpoint's engine state (the snapshot holding c, m, a...)."""
    want = {"c", "m", "free", "a", "a_last", "a_last2"}
    stack = [payload["engine"]]
    while stack:
        o = stack.pop()
        if isinstance(o, tuple) and len(o) == 2 and isinstance(o[0], str):
            o = o[1]
        if isinstance(o, dict):
            if want <= set(o):
                return {k: o[k][1] for k in want}
            stack.extend(o.values())
        elif isinstance(o, (list, tuple)):
            stack.extend(o)
    raise SystemExit("no selective-mass solver in this checkpoint")


def assemble(s, c) -> sp.csr_matrix:
    """dM = sum_e c_e (I - P_e) (3 n_node square) from the solver s's reference geometry."""
    conn = np.asarray(s.conn, np.int64)
    dX = s.X[conn] - s.Xc[:, None, :]
    J = s.Jinv[:, [0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(-1, 3, 3)
    S = np.zeros(dX.shape + (3,))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -dX[..., 2], dX[..., 1], -dX[..., 0]
    S -= np.swapaxes(S, -1, -2)
    B = -np.einsum("eaij,ejk,eblk->eaibl", S, J, S) - np.einsum("ab,ij->aibj", np.full((8, 8), 1 / 8), np.eye(3))
    for a in range(8):
        B[:, a, :, a, :] += np.eye(3)
    B *= c[:, None, None, None, None]
    dofs = (3 * conn[:, :, None] + np.arange(3)).reshape(len(conn), 24)
    n = 3 * len(s.X)
    return sp.csr_matrix((B.reshape(len(conn), -1).ravel(), (np.repeat(dofs, 24, axis=1).ravel(),
                                                              np.tile(dofs, (1, 24)).ravel())), shape=(n, n))


def pcg(A, b, D, apply_m, x0, tol, cap=1000) -> int:
    """Iterations of PCG to sqrt(r.D^-1 r) <= tol sqrt(b.D^-1 b) (the engine's rule)."""
    x = x0.copy()
    r = b - A @ x
    z = apply_m(r)
    p, rz, ref, it = z.copy(), r @ z, np.sqrt(b @ (b / D)), 0
    while np.sqrt(r @ (r / D)) > tol * ref and it < cap:
        q = A @ p
        alpha = rz / (p @ q)
        x += alpha * p
        r -= alpha * q
        z = apply_m(r)
        rz, rz_old = r @ z, rz
        p = z + rz / rz_old * p
        it += 1
    return it


def aggregates(G: sp.csr_matrix) -> np.ndarray:
    """Greedy aggregation: a node whose neighbours are all free roots an aggregate of them; leftovers join one."""
    agg = -np.ones(G.shape[0], np.int64)
    k = 0
    for i in range(G.shape[0]):
        nb = G.indices[G.indptr[i]:G.indptr[i + 1]]
        if agg[i] < 0 and np.all(agg[nb] < 0):
            agg[nb] = k
            k += 1
    for i in np.flatnonzero(agg < 0):  # every node of an element has itself and neighbours in G
        nb = G.indices[G.indptr[i]:G.indptr[i + 1]]
        agg[i] = agg[nb[agg[nb] >= 0][0]]
    return agg


def basis(X, groups, rigid: bool) -> sp.csr_matrix:
    """(3 n_node, k m) translations (m = 3) or rigid modes (m = 6) of each node group (list of node arrays)."""
    rows, cols, vals = [], [], []
    m = 6 if rigid else 3
    for j, nodes in enumerate(groups):
        r = X[nodes] - X[nodes].mean(axis=0)
        for i in range(3):
            rows.append(3 * nodes + i), cols.append(np.full(len(nodes), m * j + i)), vals.append(np.ones(len(nodes)))
        if rigid:  # (w x r)_i = e_ijk w_j r_k
            for i, jj, kk, sign in ((0, 1, 2, 1), (0, 2, 1, -1), (1, 2, 0, 1), (1, 0, 2, -1), (2, 0, 1, 1),
                                    (2, 1, 0, -1)):
                rows.append(3 * nodes + i), cols.append(np.full(len(nodes), m * j + 3 + jj))
                vals.append(sign * r[:, kk])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(3 * len(X), m * len(groups)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("deck")
    ap.add_argument("checkpoint")
    ap.add_argument("--tol", type=float, default=1e-3)
    a = ap.parse_args()
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import read_deck
    from fdeck.engine.selective_mass import SelectiveMass
    from fdeck.io.checkpoint import read_checkpoint

    problem = compile_deck(read_deck(Path(a.deck))[0], Path(a.deck).parent)
    s = SelectiveMass([g.conn for g in problem.groups], problem.X)
    saved = saved_solver(read_checkpoint(a.checkpoint))
    free = saved["free"].ravel() > 0
    A = (assemble(s, saved["c"]) + sp.diags(np.repeat(saved["m"], 3)))[free][:, free].tocsr()
    D = A.diagonal()
    b = A @ saved["a"].ravel()[free]
    guess = (2.0 * saved["a_last"] - saved["a_last2"]).ravel()[free]
    Ds = sp.diags(1 / np.sqrt(D))
    lam_max = spla.eigsh(Ds @ A @ Ds, k=1, which="LA", return_eigenvectors=False)[0]
    lam, vec = spla.eigsh(Ds @ A @ Ds, k=1, sigma=0, which="LM")
    conn = np.asarray(s.conn, np.int64)
    n = len(s.X)
    mode = np.zeros(3 * n)
    mode[free] = vec[:, 0] / np.sqrt(D)
    square = np.einsum("ij,ij->i", mode.reshape(n, 3), mode.reshape(n, 3))  # per node
    nodal = np.sort(square)[::-1]
    ratio = saved["c"] / saved["m"][conn].mean(axis=1)  # added mass per element over its nodes' mean mass
    near = ratio[np.isin(conn, np.argmax(square)).any(axis=1)]
    print(f"{A.shape[0]} free dofs, {len(s.conn)} elements; eigenvalues of D^-1 (M + dM) in "
          f"[{lam[0]:.4g}, {lam_max:.4g}]; the lowest mode has {nodal[:50].sum() / nodal.sum():.0%} of its norm "
          f"on 50 nodes, its largest at a node whose elements' c_e are {near.min():.3g}-{near.max():.3g} x their "
          f"nodes' mass; tolerance {a.tol:g}; iterations from zero / from the linear extrapolation of the two "
          "cycles before (the engine's quadratic start needs a third)")
    run = lambda apply_m: (pcg(A, b, D, apply_m, 0 * b, a.tol), pcg(A, b, D, apply_m, guess, a.tol))
    print("  Jacobi (the assembled diagonal; the engine's differs at prisms' repeated nodes): %d / %d, one product "
          "per iteration" % run(lambda r: r / D))
    G = sp.csr_matrix((np.ones(64 * len(conn)), (np.repeat(conn, 8, axis=1).ravel(), np.tile(conn, (1, 8)).ravel())),
                      shape=(n, n))
    if np.any(np.diff(G.tocsr().indptr) == 0):
        raise SystemExit("a node belongs to no hexahedron: aggregation needs every node in an element")
    agg = aggregates(G.tocsr())
    groups = [np.flatnonzero(agg == j) for j in range(agg.max() + 1)]
    omega = 1.0 / lam_max
    for rigid in (False, True):
        P0 = basis(s.X, groups, rigid)[free]
        for smoothed in (False, True):
            P = (P0 - (4 / (3 * lam_max)) * (sp.diags(1 / D) @ (A @ P0))).tocsr() if smoothed else P0
            lu = spla.splu((P.T @ A @ P).tocsc())
            coarse = lambda r, P=P, lu=lu: P @ lu.solve(P.T @ r)

            def vcycle(r, coarse=coarse):
                x = omega * r / D
                x += coarse(r - A @ x)
                return x + omega * (r - A @ x) / D
            name = f"{'rigid' if rigid else 'translations'}, {'smoothed' if smoothed else 'plain'}"
            print(f"  two-level on {len(groups)} aggregates ({n / len(groups):.1f} nodes), {name}: additive "
                  "%d / %d, V-cycle %d / %d (three products per iteration)"
                  % (run(lambda r, coarse=coarse: r / D + coarse(r)) + run(vcycle)))
    for above in (20.0, 5.0, 2.0):
        heavy = np.flatnonzero(ratio > above)
        if not len(heavy):
            continue
        E = sp.csr_matrix((np.ones(8 * len(heavy)), (np.repeat(np.arange(len(heavy)), 8), conn[heavy].ravel())),
                          shape=(len(heavy), n))
        k, label = connected_components(E @ E.T, directed=False)
        P = basis(s.X, [np.unique(conn[heavy[label == j]]) for j in range(k)], True)[free]
        lu = spla.splu((P.T @ A @ P).tocsc())
        print(f"  rigid modes of {k} clusters of the {len(heavy)} elements with c_e > {above:g} x their nodes' mass, "
              "additive: %d / %d" % run(lambda r, P=P, lu=lu: r / D + P @ lu.solve(P.T @ r)))


if __name__ == "__main__":
    main()
