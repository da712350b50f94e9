"""Static solves driven by prescribed displacements (``fdeck.engine.static``): the held dofs move in proportion to
the load factor, the reactions in the static summary, and the stability count (``negative_eigenvalues``)."""

from __future__ import annotations

import math

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spl

from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import static
from fdeck.study.static_run import run_static
from helpers import DECKS
from test_static_cantilever import strip_data


def strip(L, h, nx, nz, E, G, boundary):
    """The symmetric static strip of test_static_cantilever (clamped at x = 0, y held) with the extra boundary
    cards given, its tip's reactions reported: plain data."""
    return strip_data(L, h, nx, nz, E, G, boundary=boundary, reactions=["tip"])


def test_cantilever_pushed_by_a_prescribed_tip_displacement_against_timoshenko(tmp_path):
    """Requirement: a static run whose only loading is a prescribed displacement (the tip of a cantilever pushed
    down by delta, its rotation free) reaches equilibrium, and the summary's tip reaction equals Timoshenko's
    P = delta / (L^3 / (3 EI) + L / (k G A)), k = 5/6, within 3 %, pointing against the push: the mesh error of
    `ans` with four layers is < 1 % (test_bending_locking), and the clamped root and the tip face held flat in z
    each add an end zone of decay length ~0.45 h, ~(h/L)^2 E/G ~ 0.5 % each (measured +0.26 % in all). The
    stored energy equals P delta / 2 within 1 %: Clapeyron's identity for this linear response (delta / L =
    5e-4, geometric stiffening ~1e-7), so it checks the summary's energy sum and the reaction's sign and sum,
    not the physics."""
    L, h, E, G = 20.0, 1.0, 1000.0, 500.0
    delta = 0.01
    data = strip(L, h, 10, 4, E, G, [{"type": "displacement", "nodes": "tip", "dofs": ["z"], "value": -delta}])
    summary = run_static(data, DECKS, tmp_path / "run", {"max_iterations": 20})
    assert summary["status"] == "completed"
    EI, A = E * h * h ** 3 / 12.0, h * h
    P = delta / (L ** 3 / (3.0 * EI) + L / (5.0 / 6.0 * G * A))
    fz = summary["final"]["reaction_tip_z"]
    assert abs(-fz / P - 1.0) < 0.03, (fz, P)
    assert abs(summary["final"]["internal_energy"] / (0.5 * -fz * delta) - 1.0) < 0.01


def _column(strain):
    """The strip as a clamped-clamped column (tip: x pushed by strain * L, z held) and its straight equilibrium."""
    L, h, E, G = 40.0, 1.0, 1000.0, 500.0
    data = strip(L, h, 40, 4, E, G, [{"type": "displacement", "nodes": "tip", "dofs": ["x"], "value": -strain * L},
                                     {"type": "fixed", "nodes": "tip", "dofs": ["z"]}])
    problem = compile_deck(Deck.model_validate(data), DECKS)
    res = static.solve(problem)
    assert res.converged
    assert np.abs(res.x[:, 2] - problem.X[:, 2]).max() < 1e-9  # the straight branch (symmetric path, no bending)
    return problem, res.x, L, h, E, G


def test_negative_eigenvalues_count_the_euler_modes_a_straight_column_has_passed():
    """Requirement: ``negative_eigenvalues`` finds an unstable equilibrium. A clamped-clamped column held straight
    past Euler's loads P_n = c_n pi^2 EI / L^2 (c = 4, 8.18, 16 for the first three modes; with Timoshenko's shear
    correction P / (1 + P / (k G A)), 0.5 % here) has one negative eigenvalue per mode passed. Compressive strains
    10 % below / above the first and the second critical strains bracket them: the hexahedral column's first
    critical load sits within 1 % of the closed form (measured once: 0 negative eigenvalues at 0.99 of it, 1 at
    1.01; 40 elements per length, four through the thickness, ans without shear locking), so 10 % margins test
    the count, not the mesh."""
    L, h, E, G = 40.0, 1.0, 1000.0, 500.0
    EI, A = E * h ** 4 / 12.0, h * h

    def critical_strain(c):
        P = c * math.pi ** 2 * EI / L ** 2
        return P / (1.0 + P / (5.0 / 6.0 * G * A)) / (E * A)

    e1, e2 = critical_strain(4.0), critical_strain(8.183)
    for strain, expected in ((0.9 * e1, 0), (1.1 * e1, 1), (0.9 * e2, 1), (1.1 * e2, 2)):
        problem, x, *_ = _column(strain)
        assert static.negative_eigenvalues(problem, x) == expected, strain / e1


def test_a_static_run_that_stops_reports_the_stability_of_its_last_equilibrium(tmp_path, monkeypatch):
    """Requirement: a static study run that stops short of full load, with ``stability`` asked for, reports the
    load factor it reached and the negative eigenvalues of the tangent at its last equilibrium (what tells a lost
    stable path from a solver that did not find the next equilibrium), and saves that state. The stop is made
    here by wrapping the solver (it returns its own answer marked as not converged at load factor 0.9), on the
    clamped-clamped column held straight at 1.1 times its first Euler strain, so the count is known: 1 (the
    previous test's margin; the count 0 below the first load is that test's)."""
    L, h, E, G = 40.0, 1.0, 1000.0, 500.0
    EI, A = E * h ** 4 / 12.0, h * h
    P = 4.0 * math.pi ** 2 * EI / L ** 2
    e1 = P / (1.0 + P / (5.0 / 6.0 * G * A)) / (E * A)
    real, returned = static.solve, []

    def stopped(*args, **kw):
        res = real(*args, **kw)
        res.converged, res.load_factor = False, 0.9
        returned.append(res)
        return res

    monkeypatch.setattr(static, "solve", stopped)
    data = strip(L, h, 40, 4, E, G, [{"type": "displacement", "nodes": "tip", "dofs": ["x"], "value": -1.1 * e1 * L},
                                     {"type": "fixed", "nodes": "tip", "dofs": ["z"]}])
    summary = run_static(data, DECKS, tmp_path / "run", {"max_iterations": 20, "stability": True})
    assert summary["status"] == "failed" and summary["load_factor_reached"] == 0.9
    assert summary["negative_eigenvalues_at_stop"] == 1
    x = np.load(tmp_path / "run" / "stop_positions.npy")
    assert np.array_equal(x, returned[-1].x)  # the last equilibrium itself was saved, not the reference state
    assert np.ptp(x[:, 0]) < L * (1.0 - e1)  # the column is shortened by 1.1 e1 L


def test_stable_branch_switches_a_column_pushed_past_euler_onto_its_buckled_equilibrium():
    """Requirement: with ``stable=True`` the solver leaves a branch that has lost its stability. The clamped-clamped
    column pushed to 1.1 times its first critical strain e1 stays straight without it (one negative eigenvalue:
    the previous tests); with it the answer is the buckled column: no negative eigenvalue, the axial reaction at
    the first critical load P1 (post-buckling of the elastica: P / P1 - 1 ~ (pi a / 2 L)^2 / 4 ~ 2e-4 here) within 3 %
    (the mesh's first critical load sits within 1 % of the closed form, see above; the rest is the straight part
    of the shortening's own elastic share, under 1 %), and the mid-span deflection a of the first mode
    w = a (1 - cos 2 pi x / L) / 2 taking up the shortening beyond e1 L: int w'^2 / 2 dx = a^2 pi^2 / (4 L) =
    0.1 e1 L, so a = (2 L / pi) sqrt(0.1 e1), within 10 % (the axial strain's own share of the shortening and the
    mode's shear part move it by a few per cent)."""
    L, h, E, G = 40.0, 1.0, 1000.0, 500.0
    EI, A = E * h ** 4 / 12.0, h * h
    P = 4.0 * math.pi ** 2 * EI / L ** 2
    P1 = P / (1.0 + P / (5.0 / 6.0 * G * A))
    e1 = P1 / (E * A)
    data = strip(L, h, 40, 4, E, G, [{"type": "displacement", "nodes": "tip", "dofs": ["x"], "value": -1.1 * e1 * L},
                                     {"type": "fixed", "nodes": "tip", "dofs": ["z"]}])
    problem = compile_deck(Deck.model_validate(data), DECKS)
    res = static.solve(problem, stable=True)
    assert res.converged and res.switches >= 1 and res.unstable == 0
    assert static.negative_eigenvalues(problem, res.x) == 0
    sp_ = static.StaticProblem(problem)
    tip = problem.node_sets["tip"]
    reaction = -(sp_.f_int(res.x) - sp_.f_ext)[tip, 0].sum()
    assert abs(reaction / P1 - 1.0) < 0.03, (reaction, P1)
    mid = np.abs(problem.X[:, 0] - L / 2) < 1e-9
    a = np.abs(res.x[mid, 2] - problem.X[mid, 2]).mean()
    a_ref = 2.0 * L / math.pi * math.sqrt(0.1 * e1)
    assert abs(a / a_ref - 1.0) < 0.10, (a, a_ref)


def test_negative_direction_has_the_curvature_of_its_pivot():
    """Requirement: ``negative_direction`` returns the inertia of a sparse symmetric indefinite matrix and a
    direction v with v^T K v = 1 / D_ii < 0 for the LDL^T pivot it picks (after scaling v to largest entry 1:
    v^T K v / s^2, s the scale), on random matrices whose fill-reducing ordering is not its own inverse (so a
    permutation applied the wrong way round is seen). References: the eigenvalue count of the dense matrix;
    1e-9 relative (two triangular solves' round-off)."""
    rng = np.random.default_rng(5)
    for seed in range(5):
        n = 60
        A = sp.random(n, n, density=0.08, random_state=seed)
        K = sp.csc_matrix((A + A.T).toarray() + np.diag(rng.normal(size=n)))
        count, v = static.negative_direction(K)
        assert count == int(np.sum(np.linalg.eigvalsh(K.toarray()) < 0.0)) > 0
        lu = spl.splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        assert not np.array_equal(lu.perm_c[lu.perm_c], np.arange(n))  # the ordering is not an involution
        d = lu.U.diagonal()
        curvature = float(v @ (K @ v))
        # v was scaled to largest entry 1: compare with the pivot's 1 / D_ii at the same scale, for some pivot i
        # that is negative (the one picked: the most negative relative to K's diagonal)
        q = np.argsort(lu.perm_c)
        i = int(np.argmin(d / (np.abs(K.diagonal()[q]) + 1e-300)))
        e = np.zeros(n)
        e[i] = 1.0
        z = spl.spsolve_triangular(lu.U.tocsr(), e, lower=False)[lu.perm_c]
        scale = 1.0 / np.abs(z).max()
        assert curvature < 0.0 and abs(curvature / (scale ** 2 / d[i]) - 1.0) < 1e-9


def test_on_increment_sees_every_increment_and_the_column_turn_unstable_at_euler():
    """Requirement (the path watcher of ``studies/three_point_bending.py --onset``): ``solve(on_increment=...)`` is
    called once per converged increment with its load factor and positions, in order, the last one the answer.
    The straight clamped-clamped column pushed to 1.1 e1 (plain continuation stays straight, see above) then has
    no negative eigenvalue at the increments below e1 and one at those above: the last stable and the first
    unstable increment bracket the first critical strain, with the mesh's own e1 (within 1 % of the closed form,
    the count test above) inside the bracket (0.77-1.1 e1 at the solver's increments today)."""
    L, h, E, G = 40.0, 1.0, 1000.0, 500.0
    EI, A = E * h ** 4 / 12.0, h * h
    P = 4.0 * math.pi ** 2 * EI / L ** 2
    e1 = P / (1.0 + P / (5.0 / 6.0 * G * A)) / (E * A)
    data = strip(L, h, 40, 4, E, G, [{"type": "displacement", "nodes": "tip", "dofs": ["x"], "value": -1.1 * e1 * L},
                                     {"type": "fixed", "nodes": "tip", "dofs": ["z"]}])
    problem = compile_deck(Deck.model_validate(data), DECKS)
    seen = []
    res = static.solve(problem, on_increment=lambda lam, x: seen.append((lam, x.copy())))
    assert res.converged
    assert [lam for lam, _ in seen] == [lam for lam, _ in res.history]
    assert np.array_equal(seen[-1][1], res.x)
    counts = [(lam * 1.1, static.negative_eigenvalues(problem, x)) for lam, x in seen]
    assert all(n in (0, 1) for _, n in counts), counts
    stable = [s for s, n in counts if n == 0]
    unstable = [s for s, n in counts if n == 1]
    assert stable and unstable and max(stable) < min(unstable), counts
    assert max(stable) <= 0.99 and min(unstable) >= 1.01, counts
