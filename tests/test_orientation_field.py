"""Fibre orientation varied element by element by a cell field of the mesh file (issue 3: "or a per-element field
from the mesh file"), for hexahedra and shells, and its located input errors."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT, run_data

pytestmark = pytest.mark.unit


def write_block(path, angles=None, directions=None):
    """A 3 x 1 x 1 block of unit hexahedra written with meshio, with the cell fields given."""
    import meshio

    from fdeck.compile.mesh import block

    m = block((0, 0, 0), (3.0, 1.0, 1.0), (3, 1, 1))
    data = {}
    if angles is not None:
        data["angle"] = [np.asarray(angles, float)]
    if directions is not None:
        data["warp"] = [np.asarray(directions, float)]
    meshio.write(path, meshio.Mesh(m.X, [("hexahedron", m.cells["hexahedron"])], cell_data=data))


def hex_deck(mesh, orientation, steps=None):
    return {
        "mesh": {"file": str(mesh), "node_sets": {"xmin": {"box": [[0, 0, 0], [0, 1, 1]]},
                                                  "xmax": {"box": [[3, 0, 0], [3, 1, 1]]}}},
        "materials": {"f": {"type": "fabric_hyper", "preset": "3weave"}},
        "sections": [{"material": "f", "formulation": "fbar", "orientation": orientation}],
        "boundary": [{"type": "fixed", "nodes": "xmin"},
                     {"type": "displacement", "nodes": "xmax", "dofs": ["x", "y"], "value": 0.05,
                      "amplitude": "smooth"}],
        "steps": steps or [{"duration": 1e-3, "max_cycles": 400}],
        "output": {"history_points": 20},
    }


def group_of(data, base):
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    (g,) = compile_deck(Deck.model_validate(data), base).groups
    return g


def test_angle_field_adds_to_the_section_angle(tmp_path):
    """Requirement: a one-component field turns each element's warp by its value on top of `warp_angle`:
    warp = (cos(a + a_e), sin(a + a_e), 0) about the +z normal. Tolerance 1e-14: one rotation in double precision."""
    write_block(tmp_path / "m.vtu", angles=[0.0, 30.0, -45.0])
    g = group_of(hex_deck(tmp_path / "m.vtu", {"warp_angle": 10.0, "field": "angle"}), tmp_path)
    a = np.radians([10.0, 40.0, -35.0])
    frames = g.frame.reshape(3, -1, 3, 3)  # per element, every point the same frame
    expected = np.stack([np.cos(a), np.sin(a), np.zeros(3)], axis=1)
    for q in range(frames.shape[1]):
        assert np.abs(frames[:, q, 0] - expected).max() < 1e-14
        assert np.abs(frames[:, q, 2] - [0, 0, 1]).max() < 1e-14
        assert np.abs(np.einsum("eij,ekj->eik", frames[:, q], frames[:, q]) - np.eye(3)).max() < 1e-14


def test_direction_field_replaces_the_reference_and_is_projected(tmp_path):
    """Requirement: a three-component field is each element's reference direction, projected on the plane normal
    to `normal` and normalised (an out-of-plane part, as a draping tool may give, is dropped). Tolerance 1e-14."""
    dirs = [[0.0, 2.0, 0.0], [1.0, 1.0, 0.5], [-1.0, 0.0, 3.0]]
    write_block(tmp_path / "m.vtu", directions=dirs)
    g = group_of(hex_deck(tmp_path / "m.vtu", {"field": "warp"}), tmp_path)
    warp = g.frame.reshape(3, -1, 3, 3)[:, 0, 0]
    expected = np.array([[0, 1, 0], [1 / np.sqrt(2), 1 / np.sqrt(2), 0], [-1, 0, 0]])
    assert np.abs(warp - expected).max() < 1e-14


def test_a_uniform_field_runs_exactly_as_the_section_angle(tmp_path):
    """Requirement: a 3WEAVE block stretched along x with its warp at 30 deg gives the same history whether the
    angle comes from `warp_angle` or from a field holding 30 on every element. The frames are the same numbers,
    so the runs must agree to round-off (1e-12 of each column's largest value)."""
    write_block(tmp_path / "m.vtu", angles=[30.0, 30.0, 30.0])
    _, r1, h1 = run_data(hex_deck(tmp_path / "m.vtu", {"warp_angle": 30.0}), base=tmp_path)
    _, r2, h2 = run_data(hex_deck(tmp_path / "m.vtu", {"field": "angle"}), base=tmp_path)
    assert r1.status == r2.status == "completed"
    assert h1["internal_energy"][-1] > 0
    for c in h1:
        scale = max(np.abs(h1[c]).max(), 1e-300)
        assert np.abs(h1[c] - h2[c]).max() <= 1e-12 * scale, c


def test_shell_bases_follow_the_angle_field(tmp_path):
    """Requirement: shell Gauss-point warp directions follow the field on a flat plate (normal +z): e1 =
    (cos a_e, sin a_e, 0), e2 = z x e1. Tolerance 1e-14."""
    import meshio

    from fdeck.compile.mesh import plate

    m = plate((0, 0, 0), (3.0, 1.0), (3, 1))
    meshio.write(tmp_path / "p.vtu", meshio.Mesh(m.X, [("quad", m.cells["quad"])],
                                                 cell_data={"angle": [np.array([0.0, 45.0, 90.0])]}))
    data = {"mesh": {"file": str(tmp_path / "p.vtu")},
            "materials": {"f": {"type": "fabric_membrane", "preset": "t300_3k"}},
            "sections": [{"material": "f", "formulation": "sm", "preset": "t300_3k",
                          "orientation": {"field": "angle"}}],
            "steps": [{"duration": 1e-3}]}
    g = group_of(data, tmp_path)
    a = np.radians([0.0, 45.0, 90.0])
    e1 = np.stack([np.cos(a), np.sin(a), np.zeros(3)], axis=1)[:, None, :]
    assert np.abs(g.e1 - e1).max() < 1e-14
    assert np.abs(g.e2 - np.cross([0.0, 0.0, 1.0], e1)).max() < 1e-14


def test_a_direction_along_the_normal_is_a_located_error_naming_the_count(tmp_path):
    """Requirement: a three-component field whose direction is the sheet normal for one element (no warp can be
    projected from it) is a compile error at the section's orientation, counting that element, not a NaN frame."""
    from fdeck.compile.errors import CompileError

    write_block(tmp_path / "m.vtu", directions=[[1.0, 0.0, 0.0], [0.0, 0.0, 2.0], [0.0, 1.0, 0.0]])
    with pytest.raises(CompileError) as err:
        group_of(hex_deck(tmp_path / "m.vtu", {"field": "warp"}), tmp_path)
    ((path, message),) = err.value.problems
    assert path == ("sections", 0, "orientation") and "for 1 elements" in message


BAD = """\
mesh:
  file: m.vtu
materials:
  f: {{type: fabric_hyper, preset: 3weave}}
sections:
  - elements: all
    material: f
    orientation: {{field: {field}}}
steps:
  - {{duration: 1.0e-5}}
"""


@pytest.mark.parametrize("field,message", [("angel", "did you mean 'angle'"),
                                           ("pair", "has 2 components; expected 1 (warp angle [deg]) or 3")])
def test_bad_fields_are_located_errors_with_exit_2(tmp_path, field, message):
    """Requirement: a field the mesh lacks, or one with a component count that means nothing, is reported at the
    section's orientation key (line 8 of the deck) with exit 2 and no traceback."""
    import meshio

    from fdeck.compile.mesh import block

    m = block((0, 0, 0), (2.0, 1.0, 1.0), (2, 1, 1))
    meshio.write(tmp_path / "m.vtu", meshio.Mesh(m.X, [("hexahedron", m.cells["hexahedron"])],
                                                 cell_data={"angle": [np.zeros(2)], "pair": [np.zeros((2, 2))]}))
    deck = tmp_path / "d.yaml"
    deck.write_text(BAD.format(field=field))
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "validate", str(deck)], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "Traceback" not in r.stderr
    assert f"{deck}:8:" in r.stderr and message in r.stderr, r.stderr
