"""Static solver of compiled decks (``fdeck.engine.static``): coloured tangent and equilibrium of cantilevers."""

from __future__ import annotations

import numpy as np

from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import static
from helpers import DECKS


def strip_deck(L, h, nx, nz, E, G, ratio=1.0, tip_force=None, bending=None, gravity=False):
    """A fabric_hyper strip (quadratic modes: fibre modulus E along x and y, compaction E, shear moduli G), clamped
    at x = 0, y held, width h; a total tip force [N] along -z and/or gravity; optional fibre_bending add-on."""
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
    data = {"title": "static strip", "mesh": {"block": {"size": [L, h, h], "divisions": [nx, 1, nz]},
                                               "node_sets": {"tip": {"box": [[L, 0, 0], [L, h, h]]}}},
            "materials": {"m": mat}, "sections": [sec],
            "boundary": [{"type": "fixed", "nodes": "xmin"}, {"type": "fixed", "nodes": "all", "dofs": ["y"]}],
            "loads": loads, "steps": [{"name": "s", "duration": 1e-3}]}
    return compile_deck(Deck.model_validate(data), DECKS)


def test_coloured_tangent_equals_dense_with_fibre_bending():
    """Requirement: the coloured tangent (connectivity pattern, one pair of force calls per colour) equals the
    column-by-column finite-difference tangent, fibre_bending's neighbour coupling included, and the connectivity
    pattern holds every dependence that probing each dof alone finds. Tolerance 1e-9 of the largest entry: both use
    the same central differences, so only the summation order of the forces differs (round-off)."""
    problem = strip_deck(48.0, 1.0, 24, 2, 100.0, 10.0, ratio=0.1,
                         bending={"warp": {"D1": 5.0}, "weft": {"D1": 5.0}, "thickness": 1.0}, gravity=True)
    sp_ = static.StaticProblem(problem)
    rng = np.random.default_rng(3)
    x = problem.X + 0.02 * rng.standard_normal(problem.X.shape)  # a generic state: no symmetry hides a column
    S = sp_.dof_pattern(sp_.pattern())
    probed = sp_.probe_pattern(x)
    assert (probed.toarray() & ~S.toarray()).sum() == 0
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
