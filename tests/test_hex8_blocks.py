"""Requirement: the block path of the one-point hexahedron with linear elasticity (``hex8_blocks``: the element
update fused and vectorised over blocks of elements) gives the same bits as the general path (``hex8``'s four
passes), with stiffness and viscous hourglass control, on element counts that leave the last block partly
empty; a group whose zero coefficients keep a non-finite velocity out of the forces keeps it out on the block path
too; and it is the path such a group takes.

Reference: the general path itself, run on the same group with ``blocks`` switched off. Tolerance: zero, compared
as bit patterns (every value is formed by the same operations in the same order; a difference in the last bit,
or in the sign of a zero, would mean the block path computes something else). Checked: element forces, gathered
nodal forces, F, P, J, energy density, step moduli, hourglass energy and dissipation, the output fields, and a
whole run's history."""

from __future__ import annotations

import numpy as np
import pytest

from fdeck.compile.mesh import block
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck, Hourglass
from fdeck.engine import solver
from fdeck.physics.elements import hex8, hex8_blocks
from fdeck.registry import MATERIALS

pytestmark = pytest.mark.verification


def group(divisions, hourglass_type):
    mesh = block([0, 0, 0], [10.0, 6.0, 2.0], divisions=divisions)
    X, conn = mesh.X, np.ascontiguousarray(mesh.cells["hexahedron"], np.int64)
    n = len(conn)
    lam, mu = 120_000.0, 80_000.0
    params = np.broadcast_to(np.array([lam, mu]), (n, 2))
    g = hex8.Hex8Group("s", "reduced", X, conn, np.arange(n), MATERIALS["linear_elastic"], params,
                       np.broadcast_to(np.eye(3), (n, 3, 3)), np.full(n, 7.8e-9),
                       Hourglass(type=hourglass_type, coefficient=0.1) if hourglass_type else None)
    return g, X


def same_bits(a, b) -> bool:
    """Equal to the last bit, signed zeros and NaN payloads included (np.array_equal takes -0.0 == 0.0)."""
    a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


def compare_paths(g, x, v):
    """Run the group's update and gather with its block path, then with the general path; assert the same bits in
    every output. Returns the block path's outputs."""
    outputs = ("fe", "F", "P", "J", "psi", "modulus", "e_hg", "p_hg")
    g.update(x, v)
    fast = {k: getattr(g, k).copy() for k in outputs}
    f_fast = np.zeros_like(x)
    g.add_forces(f_fast)
    fields_fast = g.cell_fields()
    blocks, g.blocks = g.blocks, None
    for k in outputs if g.has_hourglass else outputs[:-2]:  # (without control no path writes e_hg, p_hg: zeros)
        getattr(g, k)[...] = np.nan  # the general path must write every value itself
    g.update(x, v)
    f_general = np.zeros_like(x)
    g.add_forces(f_general)
    for k in outputs:
        assert same_bits(fast[k], getattr(g, k)), k
    assert same_bits(f_fast, f_general)
    fields = g.cell_fields()
    for k in fields:
        assert same_bits(fields_fast[k], fields[k]), k
    g.blocks = blocks
    return fast


@pytest.mark.parametrize("hourglass_type", ["stiffness", "viscous", None])  # None: a group built without control
@pytest.mark.parametrize("divisions", [[10, 6, 2], [13, 7, 3]])  # 120 and 273 elements: 2 and 5 blocks, partial
def test_block_path_gives_the_bits_of_the_general_path(divisions, hourglass_type):
    g, X = group(divisions, hourglass_type)
    assert g.blocks is not None, "reduced + linear_elastic must take the block path"
    rng = np.random.default_rng(11)
    x = X + 0.05 * rng.normal(size=X.shape)  # 5 % of the smallest element edge, every mode excited
    v = rng.normal(size=X.shape) * 100.0
    fast = compare_paths(g, x, v)
    if hourglass_type:
        assert (fast["e_hg" if hourglass_type == "stiffness" else "p_hg"] > 0).all()  # the hourglass terms ran


def test_zero_coefficients_keep_a_non_finite_velocity_out_as_the_general_path_does():
    """hex8 takes no hourglass sums for an element whose coefficient is zero, so a non-finite velocity at a node of
    such elements only does not reach the forces; the block path must skip them the same way (it zeroes the sums
    per lane when a group mixes zero and nonzero coefficients): viscous group, the corner node's one element given
    a zero coefficient, that node's velocity NaN."""
    g, X = group([10, 6, 2], "viscous")
    corner = int(np.argmin(np.linalg.norm(X, axis=1)))
    only = np.nonzero((g.conn == corner).any(axis=1))[0]
    assert len(only) == 1
    g.c_hg[only] = 0.0
    g.blocks = hex8_blocks.Blocks(g.conn, g.b, g.V0, g.gamma, g.k_hg, g.c_hg, g.params)
    assert g.blocks.mixed
    rng = np.random.default_rng(5)
    x = X + 0.05 * rng.normal(size=X.shape)
    v = rng.normal(size=X.shape) * 100.0
    v[corner] = np.nan
    fast = compare_paths(g, x, v)
    assert np.isfinite(fast["fe"]).all() and np.isfinite(fast["p_hg"]).all()


def test_other_pairings_keep_the_general_path():
    assert not hex8_blocks.eligible("fbar", MATERIALS["linear_elastic"], np.array([[1.0, 2.0]]))
    assert not hex8_blocks.eligible("reduced", MATERIALS["neo_hookean"], np.array([[1.0, 2.0]]))
    assert not hex8_blocks.eligible("reduced", MATERIALS["linear_elastic"], np.array([[1.0, 2.0], [1.0, 3.0]]))


def test_a_run_on_the_block_path_gives_the_bits_of_the_general_path(monkeypatch):
    """A whole run (a cantilever under gravity, stiffness hourglass, 2 threads as the engine runs): every history
    column identical with the block path on and off."""
    data = {
        "mesh": {"block": {"size": [40.0, 4.0, 4.0], "divisions": [40, 4, 4]}},
        "materials": {"steel": {"type": "linear_elastic", "youngs_modulus": 210000.0, "poisson_ratio": 0.3,
                                "density": 7.8e-9}},
        "sections": [{"material": "steel", "formulation": "reduced"}],
        "boundary": [{"type": "fixed", "nodes": "xmin"}],
        "loads": [{"type": "gravity", "acceleration": [0, 0, -9.81e5]}],
        "steps": [{"duration": 2e-4}],
        "output": {"history_points": 50},
    }

    def run():
        res = solver.run(compile_deck(Deck.model_validate(data)), solver.Sink())
        assert res.status == "completed", res.message
        return np.array(res.history), res.final_positions

    fast_h, fast_x = run()
    monkeypatch.setattr(hex8_blocks, "eligible", lambda *a: False)
    general_h, general_x = run()
    assert same_bits(fast_h, general_h) and same_bits(fast_x, general_x)
    assert np.abs(fast_x[:, 2] - general_x[:, 2]).max() == 0.0 and fast_x[:, 2].min() < -1e-3  # it did bend
