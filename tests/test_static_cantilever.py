"""Static solver of compiled decks (``fdeck.engine.static``): coloured tangent and equilibrium of cantilevers."""

from __future__ import annotations

import numpy as np
import pytest

from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import static
from helpers import DECKS


def strip_data(L, h, nx, nz, E, G, ratio=1.0, tip_force=None, bending=None, gravity=False, ny=1, boundary=(),
               reactions=()):
    """A fabric_hyper strip (quadratic modes: fibre modulus E along x and y, compaction E, shear moduli G; `ans`
    hexahedra), clamped at x = 0, y held, width h (ny elements across), node set `tip` at x = L; a total tip force
    [N] along -z and/or gravity; optional fibre_bending add-on; extra boundary cards; reactions of named sets
    reported: plain deck data."""
    q = lambda K: {"form": "quadratic", "K": K}  # noqa: E731
    mat = {"type": "fabric_hyper", "density": 1e-9, "compression_ratio": ratio, "warp": q(E / 2), "weft": q(E / 2),
           "compaction": q(E / 2), "in_plane_shear": q(G / 2), "transverse_shear_warp": q(G / 2),
           "transverse_shear_weft": q(G / 2)}
    sec = {"elements": "all", "material": "m", "formulation": "ans"}
    if bending:
        sec["effects"] = [{"type": "fibre_bending", **bending}]
    loads = []
    if tip_force is not None:
        loads.append({"type": "nodal_force", "nodes": "tip", "force": [0, 0, -tip_force], "distribution": "total"})
    if gravity:
        loads.append({"type": "gravity", "acceleration": [0, 0, -9810]})
    data = {"title": "static strip", "mesh": {"block": {"size": [L, h, h], "divisions": [nx, ny, nz]},
                                               "node_sets": {"tip": {"box": [[L, 0, 0], [L, h, h]]}}},
            "materials": {"m": mat}, "sections": [sec],
            "boundary": [{"type": "fixed", "nodes": "xmin"}, {"type": "fixed", "nodes": "all", "dofs": ["y"]},
                         *boundary],
            "loads": loads, "steps": [{"name": "s", "duration": 1e-3}]}
    if reactions:
        data["output"] = {"reactions": list(reactions)}
    return data


def strip_deck(*args, **kw):
    """The compiled problem of ``strip_data``."""
    return compile_deck(Deck.model_validate(strip_data(*args, **kw)), DECKS)


@pytest.mark.parametrize("in_plane", [False, True])
def test_coloured_tangent_equals_dense_with_fibre_bending(in_plane):
    """Requirement: the coloured tangent (connectivity pattern, one pair of force calls per colour) equals the
    column-by-column finite-difference tangent, fibre_bending's neighbour coupling included (out of plane, and in
    plane as well), and the connectivity pattern is exactly what probing each dof alone finds at a generic state:
    every dependence (a missing one would be a wrong tangent) and nothing more (an extra one costs colours, i.e.
    force calls). Tolerance 1e-9 of the largest entry: both use the same central differences, so only the
    summation order of the forces differs (round-off)."""
    bending = {"warp": {"D1": 5.0}, "weft": {"D1": 5.0}, "thickness": 1.0}
    if in_plane:
        bending["in_plane"] = {"warp": {"D1": 3.0}, "weft": {"D1": 3.0}}
    problem = strip_deck(48.0, 4.0 if in_plane else 1.0, 24, 2, 100.0, 10.0, ratio=0.1, bending=bending,
                         gravity=True, ny=3 if in_plane else 1)
    sp_ = static.StaticProblem(problem)
    rng = np.random.default_rng(3)
    x = problem.X + 0.02 * rng.standard_normal(problem.X.shape)  # a generic state: no symmetry hides a column
    S = sp_.dof_pattern(sp_.pattern())
    probed = sp_.probe_pattern(x)
    assert (probed.toarray() != S.toarray()).sum() == 0
    assert probed.nnz > (sp_.dof_pattern(_groups_only(sp_)).nnz)  # fibre_bending reaches beyond one element
    colours = static.StaticProblem.colour(S)
    assert colours.max() + 1 < len(sp_.free) / 2  # the colouring compresses
    K = sp_.tangent(x, S, colours, 1e-6).toarray()
    Kd = sp_.dense_tangent(x, 1e-6)
    assert np.abs(K - Kd).max() <= 1e-9 * np.abs(Kd).max()


def _groups_only(sp_):
    """Node pattern of the element groups alone (an effect-free copy of ``StaticProblem.pattern``)."""
    internal, sp_.internal = sp_.internal, []
    try:
        return sp_.pattern()
    finally:
        sp_.internal = internal


def test_elastic_cantilever_against_timoshenko():
    """Requirement: the static tip deflection of an elastic cantilever (symmetric quadratic fabric, E/G = 2,
    L/h = 20, tip force giving fibre strains ~1e-4) equals Timoshenko's P L^3 / (3 EI) + P L / (k G A), k = 5/6,
    within 3 %: the mesh error of ans hexahedra with four layers and elements twice the thickness is < 1 %
    (test_bending_locking), the clamped root's end zone (decay length ~ h sqrt(E/G) / pi = 0.45 h) adds
    ~ (h/L)^2 E/G ~ 0.5 %, the lumped tip load is local."""
    L, h, E, G = 20.0, 1.0, 1000.0, 500.0
    EI = E * h * h ** 3 / 12.0
    P = 1e-4 * EI / (L * h / 2)
    problem = strip_deck(L, h, 10, 4, E, G, tip_force=P)
    res = static.solve(problem)
    assert res.converged
    tip = problem.node_sets["tip"]
    w = -(res.x[tip, 2] - problem.X[tip, 2]).mean()
    w_ref = P * L ** 3 / (3 * EI) + P * L / (5.0 / 6.0 * G * h * h)
    assert abs(w / w_ref - 1.0) < 0.03, (w, w_ref)


def test_static_equals_settled_dynamic_run():
    """Requirement: the static equilibrium of a deck equals where the explicit dynamic run of the same deck settles:
    a short elastic strip (L = 10 mm, h = 1 mm, E/G = 2, ans, 5 x 1 x 2) under gravity ramped in 0.01 s, mass-
    proportional damping 2 omega_1 (critical for the first mode, omega_1 = 3.516 sqrt(EI / (rho A L^4)) = 321 rad/s,
    the undamped run's period 0.020 s agrees), 0.15 s. Tolerance 0.5 % of the tip deflection: the residual motion
    after 0.14 s of critically damped settling is ~ omega_1 t exp(-omega_1 t) ~ 1e-18 of the first mode's, so the
    dynamic run's own drift (asserted below 0.1 %, over its last 10 %) and the explicit scheme's O(dt^2) error bound
    it; the static solve converges to 1e-8."""
    from helpers import run_data

    L, h, E, G, rho = 10.0, 1.0, 1000.0, 500.0, 1e-6
    q = lambda K: {"form": "quadratic", "K": K}  # noqa: E731
    data = {"title": "settling strip", "mesh": {"block": {"size": [L, h, h], "divisions": [5, 1, 2]},
                                                 "node_sets": {"tip": {"box": [[L, 0, 0], [L, h, h]]}}},
            "materials": {"m": {"type": "fabric_hyper", "density": rho, "compression_ratio": 1.0,
                                "warp": q(E / 2), "weft": q(E / 2), "compaction": q(E / 2),
                                "in_plane_shear": q(G / 2), "transverse_shear_warp": q(G / 2),
                                "transverse_shear_weft": q(G / 2)}},
            "sections": [{"elements": "all", "material": "m", "formulation": "ans"}],
            "boundary": [{"type": "fixed", "nodes": "xmin"}, {"type": "fixed", "nodes": "all", "dofs": ["y"]}],
            "loads": [{"type": "gravity", "acceleration": [0, 0, -9810], "amplitude": "settle"}],
            "amplitudes": {"settle": {"type": "smooth_step", "t1": 0.01}},
            "steps": [{"name": "settle", "duration": 0.15, "damping": {"mass_proportional": 642.0}}],
            "output": {"history_points": 81, "measures": [{"type": "node_displacement", "name": "tip",
                                                            "nodes": "tip", "component": "z", "reduce": "mean"}]}}
    problem, result, hist = run_data(data)
    w_dyn = -hist["tip"][-1]
    drift = abs(hist["tip"][-1] - hist["tip"][-9]) / w_dyn
    assert drift < 1e-3, drift
    res = static.solve(problem)
    assert res.converged
    tip = problem.node_sets["tip"]
    w_static = -(res.x[tip, 2] - problem.X[tip, 2]).mean()
    assert abs(w_static / w_dyn - 1.0) < 5e-3, (w_static, w_dyn, drift)
    print(f"static {w_static:.6g} dynamic {w_dyn:.6g} drift {drift:.2e}")


def _bimodular_strip(ratio, P=None):
    """(problem, P, Section) of the 20 x 1 x 1 mm ans strip (10 x 1 x 4, E = 1000, G = 500 MPa, fibres bimodular
    with compression modulus ratio * E) under a tip force P [N] giving a largest fibre strain of 1e-4."""
    from bending_helpers import Section

    L, h, E, G = 20.0, 1.0, 1000.0, 500.0
    sec = Section(E, 0.01, G, h, h)
    P = 1e-4 * sec.EI / (L * max(sec.zn, h - sec.zn)) if P is None else P
    return strip_deck(L, h, 10, 4, E, G, ratio=ratio, tip_force=P), P, sec


def _residual_from_groups(problem, x, lam=1.0):
    """|f_groups(x) - lam f_ext| / |lam f_ext| on the dofs the boundary cards leave free, computed here from the
    element groups' own forces and the loads' add_force (independent of StaticProblem.f_int/_held)."""
    n = len(problem.X)
    f = np.zeros((n, 3))
    for g in problem.groups:
        g.update(x, np.zeros((n, 3)))
        g.add_forces(f)
    fe = np.zeros((n, 3))
    for e in problem.effects:
        if e.forces == "external":
            e.add_force(problem.duration, problem.X, np.zeros((n, 3)), fe)
    free = np.ones((n, 3), bool)
    free[problem.X[:, 0] < 1e-9] = False  # fixed xmin
    free[:, 1] = False  # y held everywhere
    return np.linalg.norm((f - lam * fe)[free]) / np.linalg.norm(lam * fe[free])


def test_bimodular_cantilever_semismooth_newton():
    """Requirement: with fibres bimodular at 1 % compression (the fibre energy's kink at zero strain, here with
    the neutral axis 0.09 h from the tension face) the static solver converges, its answer's residual recomputed
    from the groups' forces is below its tolerance (1e-4 of the load), and the tip deflection equals Timoshenko's
    for the bimodular section (EI with the shifted neutral axis, shear compliance int tau^2 dA / (G V^2),
    ``bending_helpers.Section``) within 3 %: the ans element's own error on this mesh is bounded by 3 % in
    test_bending_locking, the fully clamped root's end zone (decay ~ h sqrt(E/G) / pi = 0.45 h against L = 20 h)
    and the lumped tip load add well under 1 %. The difference step straddling the kink is what made the former
    solver cycle; it is not asserted to fail here (that is a property of the old default, not a requirement)."""
    problem, P, sec = _bimodular_strip(0.01)
    res = static.solve(problem)
    assert res.converged and res.residual < 1e-4
    assert _residual_from_groups(problem, res.x) < 1e-4
    tip = problem.node_sets["tip"]
    w = -(res.x[tip, 2] - problem.X[tip, 2]).mean()
    w_ref = sec.timoshenko(P, 20.0)
    print(f"bimodular tip {w:.6g} Timoshenko {w_ref:.6g} ratio {w / w_ref:.4f} calls {res.force_calls}")
    assert abs(w / w_ref - 1.0) < 0.03, (w, w_ref)


def test_ratio_continuation_equals_direct_solve():
    """Requirement: continuation in the compression ratio (1 -> 0.1 -> 0.01, each from the previous equilibrium
    at full load) ends on the same equilibrium as the direct load-stepped solve at 1 %: tip deflections equal
    within 1e-6 relative, every node within 1e-5 of the deflection. Both converge with corrections below 1e-8 of
    the displacement, so only the convergence tolerance separates them (the equilibrium of this convex small-strain
    problem is unique)."""
    chain = static.continuation(lambda r: _bimodular_strip(r)[0], (1.0, 0.1, 0.01))
    assert chain[-1][0] == 0.01 and chain[-1][2].converged
    direct = static.solve(_bimodular_strip(0.01)[0])
    assert direct.converged
    p = chain[-1][1]
    tip = p.node_sets["tip"]
    wc = -(chain[-1][2].x[tip, 2] - p.X[tip, 2]).mean()
    wd = -(direct.x[tip, 2] - p.X[tip, 2]).mean()
    w1 = -(chain[0][2].x[tip, 2] - p.X[tip, 2]).mean()
    assert wc > 3.0 * w1  # the chain did move: 1 % compression is much softer than symmetric fibres
    assert abs(wc / wd - 1.0) < 1e-6, (wc, wd)
    assert np.abs(chain[-1][2].x - direct.x).max() < 1e-5 * wd
