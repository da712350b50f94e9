"""Static equilibrium of a compiled deck: load-stepped Newton with a coloured finite-difference tangent.

What it solves: find x (n_node, 3) [mm] with f_int(x) = lambda f_ext on the free dofs, lambda from 0 to 1, where
f_int [N] sums the element groups' forces and the effects whose forces have the resisting sign (``forces =
"internal"``: section add-ons such as ``fibre_bending``, springs), f_ext [N] the external loads (gravity, nodal
forces) at the end of the deck's last step, and the dofs that the deck's boundary cards prescribe are held at
lambda times the displacement they prescribe at that time (a punch pushed by a prescribed displacement is solved
by displacement increments). Damping forces vanish at rest and are left out. Not supported (ValueError):
rotational dofs (shells), effects with bodies of their own (tools), loads that depend on x.

Tangent: K = d f_int / dx by central differences of f_int, compressed by colouring (A.R. Curtis, M.J.D. Powell,
J.K. Reid, On the estimation of sparse Jacobian matrices, IMA J. Appl. Math. 13, 1974): two free dofs share a colour
when no force component depends on both, so perturbing every dof of one colour at once and differencing gives all
their columns from two force evaluations. The pattern comes from the connectivity (``pattern``): an element group
couples the nodes of each element; a section add-on (an effect with a ``group``) may couple the nodes of
neighbouring elements: one that names the element pairs it couples (``coupled_elements``: ``fibre_bending``'s
hinges) is given the nodes of each pair, any other the nodes of every pair of elements that share a node (a
superset); other internal effects are taken as nodal. The tighter pattern of the hinges needs fewer colours, hence
fewer force calls per tangent, for the same tangent (three-point-bending strip: 65 colours against 104 on 3 mm, 68
against 108 on 1 mm). ``probe_pattern`` finds the pattern of a small problem column by column, to check the
connectivity pattern against (tests).

Load stepping: increments of lambda grow after an increment converging in few iterations and are halved after one
that fails (no convergence, a non-finite force, an inverted element). Under prescribed displacements each increment
starts from the secant extrapolation of the last two equilibria, and the first moves the held nodes by at most a
quarter of the smallest element edge (see ``solve``). Stability of an answer: ``negative_eigenvalues`` (Sylvester's
inertia of the tangent); an equilibrium reached by continuation is not necessarily the only one, and ``stable``
checks every increment and switches off a branch that has lost its stability (see ``solve``).

Shapes: dofs numbered 3 node + component; x, X (n_node, 3) [mm]; forces (n_node, 3) [N]; K (n_free, n_free) [N/mm].
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from fdeck.engine.ledger import STORED


@dataclass
class StaticResult:
    x: np.ndarray  # (n_node, 3) equilibrium positions [mm]
    converged: bool
    load_factor: float  # lambda reached
    increments: int
    iterations: int  # Newton iterations in all
    force_calls: int
    colours: int
    wall: float  # [s]
    history: list = field(default_factory=list)  # (lambda, iterations) per converged increment
    residual: float = float("nan")  # |f_int - lambda f_ext| / |lambda f_ext| on the free dofs at the answer
    switches: int = 0  # branch switches made (``stable``)
    unstable: int = -1  # negative eigenvalues at the answer (``stable``; -1: not checked)


class StaticProblem:
    """f_int(x), f_ext, the held dofs and their positions for a compiled ``Problem``."""

    def __init__(self, problem):
        if problem.rotations is not None:
            raise ValueError("static solve: rotational dofs (shells) are not supported")
        if any(e.moves for e in problem.effects):
            raise ValueError("static solve: effects with bodies of their own (tools) are not supported")
        self.problem, self.X = problem, problem.X
        self.n = len(problem.X)
        k = len(problem.steps) - 1
        self.t = problem.duration  # loads and prescribed positions at the end of the last step
        plan = problem.steps[k]
        for g, rho in zip(problem.groups, plan.rho):
            g.set_density(rho)
        for e in problem.effects:
            e.begin_step(k, plan)
        self.internal = [e for e in problem.effects if e.forces == "internal"]
        external = [e for e in problem.effects if e.forces == "external"]
        self.f_ext = np.zeros((self.n, 3))
        for e in external:
            e.add_force(self.t, self.X, np.zeros((self.n, 3)), self.f_ext)
        f2 = np.zeros((self.n, 3))
        for e in external:  # loads must not depend on x: evaluate them at a displaced state too
            e.add_force(self.t, self.X + 1.0, np.zeros((self.n, 3)), f2)
        if not np.allclose(f2, self.f_ext, rtol=1e-12, atol=0.0):
            raise ValueError("static solve: a load depends on the positions (follower load), not supported")
        self.held, self.x_held = self._held()
        self.free = np.flatnonzero(~self.held)
        self.size = float(np.ptp(self.X, axis=0).max())  # the model's largest extent [mm]
        self.moved = self.x_held - self.X.ravel()[self.held] != 0.0  # the held dofs that the deck moves
        self.calls = 0
        self._zero = np.zeros((self.n, 3))

    def _held(self):
        """Dofs that the constraint effects overwrite (probed with two velocity fields: a held dof gets the same
        value from both) and the positions they prescribe at t (x = X + 1 s v with dt = 1 s)."""
        cons = [e for e in self.problem.effects if e.constrains]
        va, vb = np.full((self.n, 3), 1.0), np.full((self.n, 3), 2.0)
        for e in cons:
            e.constrain(self.t, 1.0, self.X.copy(), va)
            e.constrain(self.t, 1.0, self.X.copy(), vb)
        held = (va == vb).ravel()
        return held, (self.X + va).ravel()[held]

    def f_int(self, x: np.ndarray) -> np.ndarray:
        """(n_node, 3) resisting forces [N] at positions x (n_node, 3), at rest."""
        self.calls += 1
        f = np.zeros((self.n, 3))
        for g in self.problem.groups:
            g.update(x, self._zero)
            g.add_forces(f)
        for e in self.internal:
            e.add_force(self.t, x, self._zero, f)
        return f

    def potential(self, x: np.ndarray, lam: float) -> float:
        """Pi(x) = stored energy of the groups and internal effects at x - lam f_ext . (x - X) [mJ]."""
        self.f_int(x)
        return sum(self.stored().values()) - lam * float(np.sum(self.f_ext * (x - self.X)))

    def stored(self) -> dict[str, float]:
        """Stored energy [mJ] of the groups and internal effects at the last ``f_int``, by ledger term name."""
        out: dict[str, float] = {}
        for src in list(self.problem.groups) + self.internal:
            for t, v in zip(src.terms, src.term_values()):
                if t.kind == STORED:
                    out[t.name] = out.get(t.name, 0.0) + float(v)
        return out

    def smallest_edge(self) -> float:
        """Smallest nonzero distance [mm] between two nodes of one element in the reference configuration (an
        element that repeats a node, a triangle stored as a quad, has a zero one, which is no edge)."""
        out = np.inf
        for g in self.problem.groups:
            xe = self.X[np.asarray(g.conn)]  # (n_el, k, 3)
            k = xe.shape[1]
            for a in range(k):
                for b in range(a + 1, k):
                    d = np.linalg.norm(xe[:, a] - xe[:, b], axis=1)
                    d = d[d > 0.0]
                    if d.size:
                        out = min(out, float(d.min()))
        return out

    def inverted(self) -> bool:
        """True when an element of the last evaluated state has det F <= 0 (or NaN)."""
        return any(not g.worst_jacobian()[0] > 0.0 for g in self.problem.groups)

    # -------------------------------------------------------------------------------------------------- pattern
    def pattern(self) -> sp.csr_matrix:
        """(n_node, n_node) boolean node coupling from the connectivity (see the module docstring)."""
        rows, cols = [], []
        n = self.n
        for g in self.problem.groups:
            c = np.asarray(g.conn)
            rows.append(np.repeat(c, c.shape[1], axis=1).ravel())
            cols.append(np.tile(c, (1, c.shape[1])).ravel())
        for e in self.internal:
            g = getattr(e, "group", None)
            if g is None:
                continue
            c = np.asarray(g.conn)
            A = sp.csr_matrix((np.ones(c.size), (np.repeat(np.arange(len(c)), c.shape[1]), c.ravel())),
                              shape=(len(c), n))
            if hasattr(e, "coupled_elements"):  # the pairs of elements it couples, e.g. fibre_bending's hinges
                left, right = e.coupled_elements()
                pairs = sp.csr_matrix((np.ones(2 * len(left)), (np.tile(np.arange(len(left)), 2),
                                                                np.concatenate([left, right]))),
                                      shape=(len(left), len(c)))
                H = pairs @ A  # (n_pairs, n_node): the nodes of both elements of each pair
                C = (H.T @ H).tocoo()
            else:
                E = (A @ A.T).tocsr()  # elements sharing a node
                C = (A.T @ E @ A).tocoo()
            rows.append(C.row)
            cols.append(C.col)
        rows.append(np.arange(n))
        cols.append(np.arange(n))
        r, c = np.concatenate(rows), np.concatenate(cols)
        return sp.csr_matrix((np.ones(len(r), bool), (r, c)), shape=(n, n))

    def dof_pattern(self, node_pattern: sp.csr_matrix) -> sp.csr_matrix:
        """(n_free, n_free) boolean dof pattern of the free dofs."""
        S = sp.kron(node_pattern.astype(np.int8), np.ones((3, 3), np.int8), format="csr")
        return (S[self.free][:, self.free] != 0).tocsr()

    def probe_pattern(self, x: np.ndarray | None = None, h: float = 1e-6) -> sp.csr_matrix:
        """(n_free, n_free) boolean pattern found by perturbing each free dof alone (costly: for small checks)."""
        x = self.X.copy() if x is None else x
        f0 = self.f_int(x).ravel()[self.free]
        rows, cols = [], []
        for j, d in enumerate(self.free):
            xp = x.copy().ravel()
            xp[d] += h
            df = self.f_int(xp.reshape(-1, 3)).ravel()[self.free] - f0
            nz = np.flatnonzero(df != 0.0)
            rows.append(nz)
            cols.append(np.full(len(nz), j))
        r, c = np.concatenate(rows), np.concatenate(cols)
        m = len(self.free)
        return sp.csr_matrix((np.ones(len(r), bool), (r, c)), shape=(m, m))

    # ------------------------------------------------------------------------------------------------- tangent
    @staticmethod
    def colour(S: sp.csr_matrix) -> np.ndarray:
        """(n_col,) colour of each column of pattern S: greedy colouring of the column-intersection graph S^T S
        (columns sharing a nonzero row get different colours)."""
        G = (S.T.astype(np.int32) @ S.astype(np.int32)).tocsr()
        colours = np.full(S.shape[1], -1)
        for j in range(S.shape[1]):
            used = colours[G.indices[G.indptr[j]:G.indptr[j + 1]]]
            used = set(used[used >= 0].tolist())
            c = 0
            while c in used:
                c += 1
            colours[j] = c
        return colours

    def tangent(self, x: np.ndarray, S: sp.csr_matrix, colours: np.ndarray, h: float) -> sp.csc_matrix:
        """(n_free, n_free) d f_int / dx on the free dofs at x by central differences, one pair of force calls per
        colour; column j takes the rows of its pattern column from its colour's difference. Not forward
        differences, which would cost half: at a kink (bimodular fibres at zero strain, everywhere on the flat
        blank) they take the tension branch's stiffness for every point, and Newton cycles (the 1 mm three-point
        bending's first increment: 30 iterations without converging, against 12 with central differences)."""
        Sc = S.tocsc()
        data = np.empty(Sc.nnz)
        xr = x.ravel()
        for c in range(colours.max() + 1):
            cols = np.flatnonzero(colours == c)
            xp, xm = xr.copy(), xr.copy()
            d = self.free[cols]
            xp[d] += h
            xm[d] -= h
            df = (self.f_int(xp.reshape(-1, 3)).ravel() - self.f_int(xm.reshape(-1, 3)).ravel())[self.free]
            span = xp[d] - xm[d]  # the perturbation as stored (exact in floating point), not the nominal 2 h
            for j, s in zip(cols, span):
                a, b = Sc.indptr[j], Sc.indptr[j + 1]
                data[a:b] = df[Sc.indices[a:b]] / s
        return sp.csc_matrix((data, Sc.indices.copy(), Sc.indptr.copy()), shape=Sc.shape)

    def dense_tangent(self, x: np.ndarray, h: float) -> np.ndarray:
        """(n_free, n_free) the same derivative, one column at a time (reference for ``tangent``)."""
        xr = x.ravel()
        K = np.empty((len(self.free), len(self.free)))
        for j, d in enumerate(self.free):
            xp, xm = xr.copy(), xr.copy()
            xp[d] += h
            xm[d] -= h
            K[:, j] = (self.f_int(xp.reshape(-1, 3)).ravel() - self.f_int(xm.reshape(-1, 3)).ravel())[self.free] / (
                xp[d] - xm[d])
        return K


def solve(problem, first: float = 0.1, min_increment: float = 1e-4, max_iterations: int = 30, rtol: float = 1e-8,
          ftol: float = 1e-4, h: float | None = None, x0: np.ndarray | None = None, stable: bool = False,
          verbose: bool = False, on_increment=None) -> StaticResult:
    """Static equilibrium of ``problem`` (a compiled ``Problem``) under its loads at the end of its last step.

    Newton on the free dofs per load increment (the first one to ``first``; ``first = 1`` with ``x0`` a nearby
    equilibrium solves at full load at once, as ``continuation`` does; from ``x0`` without loads a failed attempt
    ends the solve, as every smaller increment would be the same problem); converged when the largest correction is
    below rtol times the largest displacement (at least rtol times the model's size) and the residual's norm below
    ftol of the load's. ``StaticResult.residual`` is that ratio at the answer.

    Kinks (bimodular fibres, compression_ratio < 1: the fibre energy's second derivative jumps at zero strain). The
    difference step h [mm] defaults to 1e-11 of the model's size (2e-9 mm on a 200 mm strip: a strain change of
    ~3e-9 on 0.6 mm elements, force round-off ~1e-6 of the difference), so that each integration point's
    difference stays on the branch the point is on, and the tangent is the Jacobian of that branch: an element of
    the generalized Jacobian, which makes this a semi-smooth Newton method with its local superlinear convergence
    (L. Qi, J. Sun, A nonsmooth version of Newton's method, Math. Programming 58, 1993); the branches are updated
    between iterations by the forces themselves, and the iteration stops when they no longer change. A step of
    1e-7 of the size (the former default) straddles the kink wherever |strain| < ~3e-5, i.e. near every neutral
    axis and everywhere at small loads: Newton then uses a tangent halfway between the branches and cycles.

    Stable branch (``stable``). Newton continuation follows the branch it is on through a bifurcation, stable or
    not: a perfect column pushed past Euler's load stays straight, and the three-point-bending strip on 1 mm
    elements reached an equilibrium with three negative eigenvalues or a stable one depending on round-off (the
    order of the tangent's colours). With ``stable`` every converged increment's tangent is checked (``inertia``);
    where it has negative eigenvalues the equilibrium is perturbed along a direction of negative curvature
    (``negative_direction``, largest entry a quarter of the smallest element edge, both signs tried) and Newton,
    which descends the potential, re-solved at the same load: the branch switch of numerical continuation
    (E. Riks, An incremental approach to the solution of snapping and buckling problems, Int. J. Solids Struct. 15,
    1979; W. Wagner, P. Wriggers, A simple method for the calculation of postcritical branches, Eng. Comput. 5,
    1988). The perturbed answer with fewer negative eigenvalues (then the lower potential, away from the start) is
    kept, up to three switches per increment. ``StaticResult.switches`` counts them, ``unstable`` is the count left
    at the answer (-1 where the factorisation cannot tell; no switch is tried then).

    ``on_increment(lam, x)``, when given, is called after every converged increment with its load factor and
    positions (n_node, 3) [mm], the solver's own array: read it, do not modify it (a study watching the path:
    ``studies/three_point_bending.py --onset``); an exception it raises ends the solve.
    """
    t0 = time.perf_counter()
    sp_ = StaticProblem(problem)
    X = sp_.X
    size = sp_.size
    h = 1e-11 * size if h is None else h
    S = sp_.dof_pattern(sp_.pattern())
    colours = StaticProblem.colour(S)
    fe = sp_.f_ext.ravel()[sp_.free]
    X_held = X.ravel()[sp_.held]
    u_held = sp_.x_held - X_held  # prescribed displacements at full load, applied in proportion to lambda
    moving = bool(np.any(u_held != 0.0))
    x = X.copy() if x0 is None else x0.copy()
    x.ravel()[sp_.held] = X_held if x0 is None else sp_.x_held
    if moving and x0 is None:
        # the first increment moves the held nodes by at most a quarter of the smallest element edge: a larger first
        # push crushes the elements next to them before anything else can move, and Newton may settle on that
        # crushed equilibrium (three-point bending on 3 mm elements pushed 4 mm at once: stored energy 1.8x the
        # equilibrium reached from smaller increments, which a slow dynamic run reaches too)
        first = min(first, 0.25 * sp_.smallest_edge() / float(np.abs(u_held).max()))
    lam, dlam = 0.0, first
    increments = iterations = 0
    history, rel = [], float("nan")
    x_prev, lam_prev = None, 0.0
    switches, unstable = 0, -1
    while lam < 1.0 and dlam >= min_increment:
        target = min(1.0, lam + dlam)
        xt = x.copy()
        if moving and x0 is None:  # (a start x0 is an answer at full load: its held dofs stay where they are)
            # secant predictor: the free dofs continue the last converged increment's motion, the held dofs go to
            # their share of the prescribed displacement (without it the first iterate crushes the elements next
            # to the moved nodes)
            if x_prev is not None:
                xt += (target - lam) / (lam - lam_prev) * (x - x_prev)
            xt.ravel()[sp_.held] = X_held + target * u_held
        xt, ok, its, rel = _newton(sp_, xt, target, fe, S, colours, h, max_iterations, rtol, ftol, verbose)
        iterations += its
        if ok and stable:
            xt, n_neg, n_sw, sw_its = _stable_branch(sp_, xt, target, fe, S, colours, h, max_iterations, rtol,
                                                     ftol)
            switches += n_sw
            iterations += sw_its  # (``its`` stays Newton's own count: it sets the next increment's size)
            unstable = n_neg
            if verbose:
                print(f"  lambda {target:.4g}: {n_neg} negative eigenvalues after {n_sw} branch switches")
        if ok:
            x_prev, lam_prev = x, lam
            if stable and n_sw:
                x_prev = None  # no secant predictor across a branch switch: the next increment starts on the new branch
            x, lam = xt, target
            increments += 1
            if on_increment is not None:
                on_increment(lam, x)
            history.append((lam, its))
            dlam = min(dlam * (2.0 if its <= 6 else 1.0), 0.5)
        elif x0 is not None and not np.any(fe):
            break  # from a start state with no loads every smaller increment is the same problem: stop, not retry
        else:
            dlam *= 0.5
    return StaticResult(x, lam >= 1.0, lam, increments, iterations, sp_.calls, int(colours.max() + 1),
                        time.perf_counter() - t0, history, rel, switches, unstable)


def _newton(sp_: StaticProblem, xt: np.ndarray, target: float, fe: np.ndarray, S, colours, h: float,
            max_iterations: int, rtol: float, ftol: float, verbose: bool = False
            ) -> tuple[np.ndarray, bool, int, float]:
    """Equilibrium at load factor ``target`` from the start xt (n_node, 3) [mm], its held dofs where they are: the
    damped, shifted Newton iteration of ``solve``. Returns (x, converged, iterations, relative residual)."""
    X, size, moved = sp_.X, sp_.size, sp_.moved
    load_norm = max(np.linalg.norm(fe), 1e-300)
    moving = bool(moved.any())
    ok, its, mu, rel = False, 0, 0.0, float("nan")
    for its in range(1, max_iterations + 1):
        f = sp_.f_int(xt)
        r = f.ravel()[sp_.free] - target * fe
        if not np.all(np.isfinite(r)) or sp_.inverted():
            break
        K = sp_.tangent(xt, S, colours, h)
        # damped, shifted Newton on the potential Pi = stored - lambda f_ext . u (gradient r): solve
        # (K + mu D) du = -r, D = diag |K|, with mu raised when the step has to be cut back and lowered when the
        # full step passes Armijo's test (a Levenberg-Marquardt shift: far from equilibrium the tangent of a
        # nearly straight strip is a poor model of the state it leads to). Near convergence Pi's round-off
        # hides the decrease, so there a step that lowers |r| is accepted as well.
        D = sp.diags(np.abs(K.diagonal()) + 1e-300)
        try:
            du = spl.spsolve((K + mu * D).tocsc(), -r) if mu > 0 else spl.spsolve(K, -r)
        except RuntimeError:
            break
        if not np.all(np.isfinite(du)):
            break
        pi0, slope, rn0 = sp_.potential(xt, target), float(r @ du), np.linalg.norm(r)
        if not slope < 0.0:  # not a descent direction: steepest descent, scaled to Newton's length
            du = -r * (np.linalg.norm(du) / rn0)
            slope = float(r @ du)
            mu = max(10.0 * mu, 1e-3)
        step = 1.0
        for _ in range(12):
            trial = xt.copy()
            trial.ravel()[sp_.free] += step * du
            pit = sp_.potential(trial, target)
            if np.isfinite(pit) and not sp_.inverted():
                if pit <= pi0 + 1e-4 * step * slope:
                    break
                if abs(slope) < 1e-10 * abs(pi0) and np.linalg.norm(
                        sp_.f_int(trial).ravel()[sp_.free] - target * fe) < rn0:
                    break
            step *= 0.5
        mu = mu * 0.25 if step == 1.0 else max(10.0 * mu, 1e-3)
        if mu < 1e-8:
            mu = 0.0
        xt = trial
        du = step * du
        if verbose:
            print(f"  lambda {target:.4g} it {its} |r| {rn0:.3e} step {step:g} mu {mu:.1e} "
                  f"|du| {np.abs(du).max():.3e}")
        scale = max(np.abs(xt - X).max(), size * 1e-6)
        if np.abs(du).max() < rtol * scale:
            fi = sp_.f_int(xt).ravel()
            rn = fi[sp_.free] - target * fe
            # the load's scale: the applied loads, or under prescribed displacements the reactions of the moved
            # dofs (not of the merely held ones, whose reactions do no work)
            ref = max(target * load_norm, float(np.linalg.norm(fi[sp_.held][moved])) if moving else 0.0)
            rel = float(np.linalg.norm(rn) / ref)
            ok = rel < ftol and not sp_.inverted()
            break
    return xt, ok, its, rel


def _stable_branch(sp_: StaticProblem, x: np.ndarray, lam: float, fe: np.ndarray, S, colours, h: float,
                   max_iterations: int, rtol: float, ftol: float) -> tuple[np.ndarray, int, int, int]:
    """(x, negative eigenvalues at x or -1 when the factorisation cannot tell, switches made, Newton iterations
    spent) after at most three branch switches from the equilibrium x at load factor lam (see ``solve``,
    ``stable``). A candidate is taken when it has fewer negative eigenvalues, or as many and a lower potential at
    a distance from x (not Newton falling back onto x)."""
    try:
        n_neg, mode = negative_direction(sp_.tangent(x, S, colours, h))
    except (ValueError, RuntimeError):  # off-diagonal pivots, a singular tangent: stability unknown, no switch
        return x, -1, 0, 0
    switches = iterations = 0
    apart = rtol * 1e3 * max(float(np.abs(x - sp_.X).max()), 1e-300)  # far beyond the solver's own tolerance
    amplitude = 0.25 * sp_.smallest_edge() if n_neg > 0 else 0.0
    while n_neg > 0 and switches < 3:
        best = None
        for sign in (1.0, -1.0):
            trial = x.copy()
            trial.ravel()[sp_.free] += sign * amplitude * mode
            y, ok, its, _ = _newton(sp_, trial, lam, fe, S, colours, h, max_iterations, rtol, ftol)
            iterations += its
            if not ok or np.abs(y - x).max() < apart:
                continue
            try:
                n, v = negative_direction(sp_.tangent(y, S, colours, h))
            except (ValueError, RuntimeError):
                continue
            key = (n, sp_.potential(y, lam))
            if best is None or key < best[0]:
                best = (key, y, v)
        if best is None or best[0] >= (n_neg, sp_.potential(x, lam)):
            break  # no switch leads anywhere better: keep the branch (its count is reported)
        (n_neg, _), x, mode = best
        switches += 1
    return x, n_neg, switches, iterations


def continuation(make, params, x0: np.ndarray | None = None, max_inserts: int = 6, **kw) -> list:
    """Equilibria along a parameter path (e.g. the fibre compression ratio 1, 0.3, 0.1, 0.03, 0.01), each solved at
    full load in one increment from the previous equilibrium (the first one by load steps from the flat state, or
    from ``x0``). ``make(param)`` compiles the problem at ``param`` (same mesh). A step that fails is halved
    geometrically (sqrt(previous * next) inserted before it, at most ``max_inserts`` times in all): natural
    parameter continuation with step control (E.L. Allgower, K. Georg, Numerical continuation methods,
    Springer 1990). Why: the symmetric law has no kink and converges from the flat strip; each softer law starts
    where the Newton iterates are close to their answer, so its first tangents already sit on the right branches.

    Returns [(param, problem, StaticResult)] of every attempt in order, failed ones included (their cost counts);
    the path reached its end when the last entry is ``params[-1]`` and converged."""
    queue, out, x, prev, inserts = list(params), [], x0, None, 0
    while queue:
        p = queue[0]
        problem = make(p)
        r = solve(problem, x0=x, first=1.0, **kw) if x is not None else solve(problem, **kw)
        out.append((p, problem, r))
        if r.converged:
            x, prev = r.x, p
            queue.pop(0)
        elif prev is not None and inserts < max_inserts:
            queue.insert(0, float(np.sqrt(prev * p)))
            inserts += 1
        else:
            break
    return out


def negative_eigenvalues(problem, x: np.ndarray, h: float | None = None) -> int:
    """Number of negative eigenvalues of the tangent stiffness d f_int / dx on the free dofs at x (n_node, 3) [mm]:
    0 at a stable equilibrium of a displacement-driven or dead-loaded problem (``inertia``; K is the
    finite-difference tangent, symmetrised)."""
    sp_ = StaticProblem(problem)
    S = sp_.dof_pattern(sp_.pattern())
    return inertia(sp_.tangent(x, S, StaticProblem.colour(S), 1e-11 * sp_.size if h is None else h))


def inertia(K: sp.spmatrix) -> int:
    """Number of negative eigenvalues of the symmetric part of K (n, n) (``negative_direction``'s count)."""
    return negative_direction(K, direction=False)[0]


def negative_direction(K: sp.spmatrix, direction: bool = True) -> tuple[int, np.ndarray | None]:
    """(number of negative eigenvalues of the symmetric part of K (n, n), a direction v (n,) of negative curvature,
    v^T K v < 0, largest entry 1; None when the count is 0 or ``direction`` is False).

    Sylvester's law of inertia: a symmetric K with A = K[q][:, q] = L D L^T has as many negative eigenvalues as D
    has negative entries. The LDL^T comes from SuperLU with pivots kept on the diagonal in a symmetric ordering
    (``SymmetricMode``, no threshold pivoting, perm_r = perm_c = p: row and column j of K go to position p[j], so
    q = argsort(p)), where U = D L^T and U's diagonal is D; the count is refused (ValueError) if SuperLU permuted
    rows and columns differently anyway. The direction: z = U^-1 e_i gives z^T A z = 1 / D_ii, and v = z[p] (v_j =
    z at K's index j's position) gives v^T K v = 1 / D_ii; the pivot i most negative relative to its diagonal entry
    of K is taken: a direction along which the energy falls (a negative-curvature direction from the factors, as
    modified-Cholesky optimisers take; not the eigenvector, which Lanczos about zero misses when small positive
    eigenvalues crowd it, as on the 1 mm bending strip)."""
    K = (0.5 * (K + K.T)).tocsc()
    lu = spl.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    if not np.array_equal(lu.perm_r, lu.perm_c):
        raise ValueError("negative_eigenvalues: the factorisation pivoted off the diagonal; inertia not available")
    d = lu.U.diagonal()
    count = int(np.sum(d < 0.0))
    if count == 0 or not direction:
        return count, None
    p = lu.perm_c
    q = np.argsort(p)  # A = K[q][:, q]
    i = int(np.argmin(d / (np.abs(K.diagonal()[q]) + 1e-300)))
    e = np.zeros(len(d))
    e[i] = 1.0
    v = spl.spsolve_triangular(lu.U.tocsr(), e, lower=False)[p]
    return count, v / np.abs(v).max()
