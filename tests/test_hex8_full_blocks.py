"""Requirement: the block passes of the eight-point hexahedron (``hex8_full_blocks``: kinematics and forces of
``full`` and ``fbar`` over blocks of elements, lanes innermost) give the same bits as ``hex8``'s element-by-element
passes, with any law between them, on element counts that leave the last block partly empty, for distorted,
collapsed (prism) and inverted elements; they are the path such groups take (and not the ``ans`` groups, which
have their own update); and a whole run's history is the same bits with them on and off.

Reference: ``hex8``'s own passes, run on the same group with the blocks switched off. Tolerance: zero, compared as
bit patterns (every value is formed by the same operations in the same order; a last-bit difference, a signed zero
or a different NaN would mean the block path computes something else). Checked: element forces, gathered nodal
forces, F, J, and for F-bar Fbar, Jbar, the ratios and pressures, P, energy density, step moduli, output fields."""

from __future__ import annotations

import numpy as np
import pytest

import fdeck.cards.fabric_hyper as fc
import fdeck.physics.materials.fabric_hyper as fh
from fdeck.compile.mesh import block
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import solver
from fdeck.physics.elements import hex8
from fdeck.registry import MATERIALS

pytestmark = pytest.mark.verification

LAWS = {
    "linear_elastic": np.array([120_000.0, 80_000.0]),
    "fabric_hyper": fh.pack(fc.FabricHyper(type="fabric_hyper", preset="3weave")),
}


def group(formulation, law, divisions):
    mesh = block([0, 0, 0], [10.0, 6.0, 2.0], divisions=divisions)
    X, conn = mesh.X, np.array(mesh.cells["hexahedron"], np.int64)
    conn[0, [2, 6]] = conn[0, [1, 5]]  # the first element collapsed to a prism (a repeated edge)
    n = len(conn)
    p = LAWS[law]
    g = hex8.Hex8Group("s", formulation, X, conn, np.arange(n), MATERIALS[law], np.broadcast_to(p, (n, len(p))),
                       np.broadcast_to(np.eye(3), (n, 3, 3)), np.full(n, 1e-9))
    return g, X


def same_bits(a, b) -> bool:
    """Equal to the last bit, signed zeros and NaN payloads included (np.array_equal takes -0.0 == 0.0)."""
    a, b = np.ascontiguousarray(a, float), np.ascontiguousarray(b, float)
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@pytest.mark.parametrize("law", sorted(LAWS))
@pytest.mark.parametrize("formulation", ["full", "fbar"])
@pytest.mark.parametrize("divisions", [[1, 1, 1], [13, 7, 3]])  # 1 and 273 elements: one block, five (partial)
def test_block_passes_give_the_bits_of_the_element_passes(formulation, law, divisions):
    g, X = group(formulation, law, divisions)
    assert g.full_blocks is not None, f"{formulation} must take the block passes"
    rng = np.random.default_rng(3)
    x = X + 0.05 * rng.normal(size=X.shape)  # 5 % of the smallest edge: every mode of every element excited
    if len(g.conn) > 1:
        last = g.conn[-1]
        x[last[4:]] = x[last[:4]] - [0.0, 0.0, 0.1]  # the last element turned inside out (J < 0, F-bar's NaN ratio)
    outputs = ["fe", "F", "J", "P", "psi", "modulus"] + (["Fbar", "Jbar", "ratio", "p"] if formulation == "fbar"
                                                         else [])
    g.update(x, np.zeros_like(x))
    fast = {k: getattr(g, k).copy() for k in outputs}
    f_fast = np.zeros_like(x)
    g.add_forces(f_fast)
    with np.errstate(invalid="ignore"):  # (the inverted element's F-bar fields are NaN)
        fields_fast = g.cell_fields()
    g.dN, g.full_blocks = g.dN, None  # (the element passes read the engine layout, rebuilt from the blocks)
    for k in outputs:
        getattr(g, k)[...] = np.nan  # the element passes must write every value themselves
    g.update(x, np.zeros_like(x))
    f_ref = np.zeros_like(x)
    g.add_forces(f_ref)
    for k in outputs:
        assert same_bits(fast[k], getattr(g, k)), k
    assert same_bits(f_fast, f_ref)
    with np.errstate(invalid="ignore"):
        fields = g.cell_fields()
    for k in fields:
        assert same_bits(fields_fast[k], fields[k]), k
    if len(g.conn) > 1:  # the cases meant: an inverted element (its neighbours partly), the rest finite
        assert (g.J[-1] < 0).all() and np.isfinite(g.fe).all(axis=(1, 2)).sum() >= len(g.conn) - 4


def test_ans_groups_keep_their_own_update():
    mesh = block([0, 0, 0], [4.0, 2.0, 1.0], divisions=[4, 2, 1])
    data = {"mesh": {"block": {"size": [4.0, 2.0, 1.0], "divisions": [4, 2, 1]}},
            "materials": {"f": {"type": "3weave"}}, "sections": [{"material": "f", "formulation": "ans_fbar"}],
            "steps": [{"duration": 1e-6}]}
    g = compile_deck(Deck.model_validate(data)).groups[0]
    assert len(g.conn) == len(mesh.cells["hexahedron"]) and g.full_blocks is None


@pytest.mark.parametrize("formulation", ["full", "fbar"])
def test_a_run_on_the_block_passes_gives_the_bits_of_the_element_passes(monkeypatch, formulation):
    """A whole run (a 3WEAVE strip sheared and compacted by its top face, 2 threads as the engine runs): every
    history column and the final positions identical with the block passes on and off."""
    data = {
        "mesh": {"block": {"size": [20.0, 4.0, 2.5], "divisions": [10, 2, 3]}},
        "materials": {"fabric": {"type": "3weave"}},
        "sections": [{"material": "fabric", "formulation": formulation}],
        "boundary": [{"type": "fixed", "nodes": "zmin"},
                     {"type": "displacement", "nodes": "zmax", "dofs": ["x"], "value": 1.5},
                     {"type": "displacement", "nodes": "zmax", "dofs": ["z"], "value": -0.8}],
        "steps": [{"duration": 1e-3}],
        "output": {"history_points": 50},
    }

    def run():
        problem = compile_deck(Deck.model_validate(data))
        used = problem.groups[0].full_blocks is not None
        res = solver.run(problem, solver.Sink())
        assert res.status == "completed", res.message
        return np.array(res.history), res.final_positions, used

    fast_h, fast_x, used = run()
    assert used
    monkeypatch.setattr(hex8.hex8_full_blocks, "Blocks", lambda *a: None)
    ref_h, ref_x, used = run()
    assert not used
    assert same_bits(fast_h, ref_h) and same_bits(fast_x, ref_x)
    assert fast_x[:, 2].max() < 2.5 - 0.79 and fast_x[:, 0].max() > 20.0 + 1.49  # it did shear and compact
