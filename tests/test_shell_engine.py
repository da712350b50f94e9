"""Shells in the engine: determinism across thread counts, hexahedra and shells in one deck, located input errors,
and decks without shells untouched by the rotational machinery."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT, digests_on_one_and_two_threads, run_data
from shell_helpers import linear_fabric

pytestmark = pytest.mark.unit

SCRIPT = """
import hashlib, sys, numba
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine import solver
solver.SERIAL_BELOW = 0  # use every thread even on this small model
form = sys.argv[1]
section = {"formulation": form, "preset": "t300_3k"}
material = "t300_3k_ts" if form == "ts" else "t300_3k"
d = Deck.model_validate({
    "mesh": {"plate": {"size": [20, 20], "divisions": [20, 20]}},
    "materials": {"f": {"type": "fabric_membrane", "preset": material}},
    "sections": [dict(material="f", orientation={"warp_angle": 30}, **section)],
    "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x", "y", "z", "rx", "ry", "rz"]},
                 {"type": "velocity", "nodes": "xmax", "dofs": ["x", "z"], "value": -500.0}],
    "steps": [{"duration": 1.0, "max_cycles": 60, "damping": {"mass_proportional": 100.0},
               "deformation_damping": {"rate": 1000.0}}],
    "output": {"history_points": 2}})
p = compile_deck(d)
r = solver.run(p, solver.Sink())
h = hashlib.sha256(r.final_positions.tobytes() + r.final_directors.tobytes()).hexdigest()
print(numba.get_num_threads(), h)
"""


@pytest.mark.parametrize("form", ["sm", pytest.param("ts", marks=pytest.mark.nightly)])  # ts nightly: CI budget
def test_shell_results_identical_on_one_and_two_threads(form):
    """Requirement: final positions and directors of a shell run (400 elements, 60 cycles, mass and deformation
    damping) are bitwise equal with NUMBA_NUM_THREADS=1 and 2 (per-element buffers and the fixed-order gather, for
    moments too)."""
    assert len(digests_on_one_and_two_threads(SCRIPT, form)) == 1


def mixed_mesh(path):
    """A hexahedral core 10 x 2 x 2 mm (5 x 1 x 2 elements) with a shell skin on its top face (z = 2, 5 x 1
    quadrilaterals sharing the core's top nodes), written with meshio (both cell types in one file)."""
    import meshio

    from fdeck.compile.mesh import block

    core = block((0, 0, 0), (10.0, 2.0, 2.0), (5, 1, 2))
    X = core.X
    top = core.node_sets["zmax"]
    key = {tuple(np.round(X[i], 9)): i for i in top}
    quads = []
    for i in range(5):
        xs = (2.0 * i, 2.0 * i + 2.0)
        quads.append([key[(xs[0], 0.0, 2.0)], key[(xs[1], 0.0, 2.0)], key[(xs[1], 2.0, 2.0)], key[(xs[0], 2.0, 2.0)]])
    meshio.write(path, meshio.Mesh(X, [("hexahedron", core.cells["hexahedron"]), ("quad", np.array(quads))]))


def test_hexahedra_and_shells_live_in_one_deck(tmp_path):
    """Requirement: a deck with a hexahedral section and a shell section sharing nodes compiles and runs; pulled
    uniformly, core and skin act as parallel springs: the reaction is (E_core A_core + E_skin h b) u / L within
    0.5 % (uniform strain is exact for both elements; what is left is the quasi-static remainder of the loading),
    and the run's energy balance closes (< 1e-6 of the work)."""
    mixed_mesh(tmp_path / "mixed.vtu")
    E_core, E_skin, h = 1000.0, 5.0e4, 0.2
    u, L, b, H = 0.01, 10.0, 2.0, 2.0
    data = {
        "mesh": {"file": str(tmp_path / "mixed.vtu"),
                 "node_sets": {"xmin": {"box": [[0, 0, 0], [0, 2, 2]]}, "xmax": {"box": [[10, 0, 0], [10, 2, 2]]}},
                 "element_sets": {"core": {"box": [[0, 0, 0], [10, 2, 1.9]]},
                                  "skin": {"box": [[0, 0, 2], [10, 2, 2]]}}},
        "materials": {"core": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": E_core,
                               "poisson_ratio": 0.0},
                      "skin": linear_fabric(E_skin, G=100.0)},
        "sections": [{"elements": "core", "material": "core", "formulation": "full"},
                     {"elements": "skin", "material": "skin", "formulation": "sm", "thickness": h,
                      "bending_stiffness": 1.0, "twisting_stiffness": 0.5}],
        "boundary": [{"type": "fixed", "nodes": "xmin", "dofs": ["x"]},
                     {"type": "fixed", "nodes": "all", "dofs": ["y", "z"]},
                     {"type": "displacement", "nodes": "xmax", "dofs": ["x"], "value": u, "amplitude": "smooth"}],
        "steps": [{"duration": 2e-4, "damping": {"mass_proportional": 2e5}}],
        "output": {"history_points": 20, "reactions": ["xmax"]},
    }
    problem, result, hist = run_data(data, base=tmp_path)
    assert result.status == "completed", result.message
    assert {g.cell_type for g in problem.groups} == {"hexahedron", "quad"}
    exact = (E_core * b * H + E_skin * h * b) * u / L
    assert hist["reaction_xmax_x"][-1] == pytest.approx(exact, rel=0.005)
    assert abs(hist["energy_balance_error"]).max() < 1e-6 * hist["external_work"].max()


BASE = """\
mesh:
  file: {mesh}
  element_sets:
    core: {{box: [[0, 0, 0], [10, 2, 1.9]]}}
    skin: {{box: [[0, 0, 2], [10, 2, 2]]}}
  node_sets:
    bottom: {{box: [[0, 0, 0], [10, 2, 0]]}}
materials:
  core: {{type: linear_elastic, density: 1.0e-9, youngs_modulus: 1000, poisson_ratio: 0.0}}
  skin: {{type: fabric_membrane, preset: t300_3k}}
sections:
{sections}
boundary:
{boundary}
loads:
{loads}
steps:
  - {{duration: 1.0e-4}}
"""


def validate(tmp_path, sections, boundary="  []", loads="  []"):
    mixed_mesh(tmp_path / "mixed.vtu")
    deck = tmp_path / "deck.yaml"
    deck.write_text(BASE.format(mesh=tmp_path / "mixed.vtu", sections=sections, boundary=boundary, loads=loads))
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "validate", str(deck)], cwd=ROOT, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    return [ln for ln in r.stderr.splitlines() if ln.startswith(str(deck)) and ": warning: " not in ln]


def test_shell_input_errors_are_located(tmp_path):
    """Requirement: shell mistakes are located errors with exit 2 and no traceback: a misspelt formulation (with a
    did-you-mean), a shell section without thickness or preset, a shell formulation on hexahedra, a non-plane-
    stress law on shells, rotational dofs and moments on nodes without rotations."""
    lines = validate(tmp_path, "  - {elements: core, material: core, formulation: full}\n"
                               "  - {elements: skin, material: skin, formulation: smm, preset: t300_3k}\n"
                               "  - {elements: skin, material: skin, formulation: ts, points: 3, "
                               "transverse_shear_modulus: 0.01}")
    assert len(lines) == 2, lines
    assert "sections[1].formulation: unknown formulation 'smm' (did you mean 'sm'?)" in lines[0]
    assert "sections[2]: ts: thickness not defined by the deck or a preset" in lines[1]
    lines = validate(tmp_path, "  - {elements: core, material: skin, formulation: sm, preset: t300_3k}\n"
                               "  - {elements: skin, material: core, formulation: sm, preset: t300_3k}")
    text = "\n".join(lines)  # (elements left without a section are reported too)
    assert "sections[0].elements: formulation 'sm' takes quad or triangle elements; set 'core' holds 10 " \
           "hexahedron elements" in text
    assert "sections[1].material: formulation 'sm' needs a plane-stress law; 'core' is linear_elastic" \
        in text
    lines = validate(tmp_path, "  - {elements: core, material: core, formulation: full}\n"
                               "  - {elements: skin, material: skin, formulation: membrane, thickness: 0.23}",
                     boundary="  - {type: fixed, nodes: bottom, dofs: [x, rx]}",
                     loads="  - {type: nodal_moment, nodes: bottom, moment: [0, 1, 0]}")
    assert len(lines) == 2, lines
    assert "boundary[0].dofs: rotational dofs need nodes with rotations (shell nodes); set 'bottom' has none" \
        in lines[0]
    assert "loads[0].nodes: set 'bottom' has no node with rotations (shell nodes)" in lines[1]


def test_decks_without_shells_have_no_rotational_state():
    """Requirement: a solid-only deck compiles without rotational arrays, runs no rotational kernel and keeps its
    history columns (the regression gold and the histories stay as they were)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import read_deck
    from fdeck.engine import solver
    from helpers import DECKS

    deck, _, _ = read_deck(DECKS / "cantilever.yaml")
    problem = compile_deck(deck, DECKS)
    assert problem.rotations is None
    cols = solver.history_columns(problem)
    assert cols == ["time", "dt", "kinetic_energy", "internal_energy", "strain_energy", "hourglass_energy",
                    "damping_energy", "external_work", "energy_balance_error", "reaction_xmin_x", "reaction_xmin_y",
                    "reaction_xmin_z"]
    assert not any(getattr(o, "rotational", False) for o in problem.groups + problem.effects)
