"""Requirement: the block path of the one-point hexahedron with linear elasticity (``hex8_blocks``: the element
update fused and vectorised over blocks of elements) gives the same bits as the general path (``hex8``'s four
passes), with stiffness and viscous hourglass control (and a group where some coefficients are zero), on
element counts that leave the last block partly empty; and it is the path such a group takes.

Reference: the general path itself, run on the same group with ``blocks`` switched off. Tolerance: zero (every
value is formed by the same operations in the same order; a difference in the last bit would mean the block path
computes something else). Checked: element forces, gathered nodal forces, F, P, J, energy density, step moduli,
hourglass energy and dissipation, the output fields, and a whole run's history."""

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
                       Hourglass(type=hourglass_type, coefficient=0.1))
    return g, X


@pytest.mark.parametrize("hourglass_type", ["stiffness", "viscous", "mixed"])
@pytest.mark.parametrize("divisions", [[10, 6, 2], [13, 7, 3]])  # 120 and 273 elements: 2 and 5 blocks, partial
def test_block_path_gives_the_bits_of_the_general_path(divisions, hourglass_type):
    g, X = group(divisions, "stiffness" if hourglass_type == "mixed" else hourglass_type)
    assert g.blocks is not None, "reduced + linear_elastic must take the block path"
    if hourglass_type == "mixed":  # some coefficients zero: hex8 skips those elements' sums, so must the blocks
        g.k_hg[::3] = 0.0
        g.blocks = hex8_blocks.Blocks(g.conn, g.b, g.V0, g.gamma, g.k_hg, g.c_hg, g.params)
        assert g.blocks.mixed
    rng = np.random.default_rng(11)
    x = X + 0.05 * rng.normal(size=X.shape)  # 5 % of the smallest element edge, every mode excited
    v = rng.normal(size=X.shape) * 100.0
    outputs = ("fe", "F", "P", "J", "psi", "modulus", "e_hg", "p_hg")

    g.update(x, v)
    fast = {k: getattr(g, k).copy() for k in outputs}
    f_fast = np.zeros_like(x)
    g.add_forces(f_fast)
    fields_fast = g.cell_fields()
    blocks, g.blocks = g.blocks, None
    for k in outputs:
        getattr(g, k)[...] = np.nan  # the general path must write every value itself
    g.update(x, v)
    f_general = np.zeros_like(x)
    g.add_forces(f_general)
    for k in outputs:
        assert np.array_equal(fast[k], getattr(g, k)), k
    assert np.array_equal(f_fast, f_general)
    fields = g.cell_fields()
    for k in fields:
        assert np.array_equal(fields_fast[k], fields[k]), k
    hourglass_energy = {"stiffness": fast["e_hg"], "viscous": fast["p_hg"], "mixed": fast["e_hg"][1::3]}
    assert (hourglass_energy[hourglass_type] > 0).all()  # the hourglass terms were exercised
    g.blocks = blocks


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
    assert np.array_equal(fast_h, general_h) and np.array_equal(fast_x, general_x)
    assert np.abs(fast_x[:, 2] - general_x[:, 2]).max() == 0.0 and fast_x[:, 2].min() < -1e-3  # it did bend
