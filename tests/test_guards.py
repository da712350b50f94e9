"""Guards during a run (issue 11, part 4): a collapsing stable step stops the run naming the element that sets it;
a NaN names the first node; a failed run's summary points at the last good frame."""

from __future__ import annotations

import meshio
import numpy as np

from tests.test_restart import run, write_deck

TWO_MATERIALS = """title: one stiff element
mesh:
  block: {size: [30, 10, 10], divisions: [3, 1, 1]}
  element_sets:
    stiff: {box: [[20, 0, 0], [30, 10, 10]]}
    soft: {box: [[0, 0, 0], [20, 10, 10]]}
materials:
  hard: {type: neo_hookean, density: 1.0e-9, youngs_modulus: 1000.0, poisson_ratio: 0.3}
  rubber: {type: neo_hookean, density: 1.0e-9, youngs_modulus: 10.0, poisson_ratio: 0.3}
sections:
  - {elements: stiff, material: hard, formulation: full}
  - {elements: soft, material: rubber, formulation: full}
boundary:
  - {type: fixed, nodes: zmin, dofs: [x, y, z]}
  - {type: velocity, nodes: zmax, dofs: [z], value: -2000.0, amplitude: constant}
steps:
  - {name: crush, duration: 2.0e-3, min_dt_ratio: 0.98}
output:
  frames: 40
  formats: [vtu]
  history_points: 50
"""


def test_collapsing_step_names_the_element_and_keeps_the_last_good_frame(tmp_path):
    """Requirement: when the stable step falls below min_dt_ratio x the step's first one, the run stops with exit 4
    and a message naming the element that sets the step; here the one element of the 100x stiffer section (its
    wave speed is 10x the others', so it alone sets the step; reference: the compiled section's element id). The
    summary's last good frame is earlier than the stop and holds finite displacements, and the stop happens once
    the step has fallen by 2 % (the collapse ratio asked), not before: the last history dt is within 2 % of the
    first (tolerance: the ratio itself)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import read_deck

    path = write_deck(tmp_path, TWO_MATERIALS)
    deck, _, _ = read_deck(path)
    problem = compile_deck(deck, path.parent)
    (stiff,) = [g for g in problem.groups if g.section_index == 0]
    assert len(stiff.ids) == 1
    out = tmp_path / "out"
    code, summary = run(path, out)
    assert code == 4 and summary["status"] == "failed"
    assert "collapsed" in summary["message"] and f"element {int(stiff.ids[0])} (" in summary["message"]
    good = summary["last_good_frame"]
    assert 0 < good["time"] < summary["simulated_time"]
    frame = meshio.read(out / f"deck_{good['index']:05d}.vtu")
    assert np.isfinite(frame.point_data["displacement"]).all()
    dts = [row for row in (out / "history.csv").read_text().splitlines()[1:]]
    dt = np.array([float(r.split(",")[1]) for r in dts])
    assert dt[-1] >= 0.98 * dt[0] * (1 - 1e-12) and summary["dt_min"] < dt[0]


def test_first_bad_node_is_named():
    """Requirement: a non-finite value names the first node (1-based) holding one in any of the arrays given
    (reference: the rows planted with NaN and inf)."""
    from fdeck.engine.solver import RunStopped, first_bad_node

    x, v = np.zeros((10, 3)), np.zeros((10, 3))
    assert first_bad_node(x, v) is None
    v[7, 2] = np.nan
    x[4, 0] = np.inf
    assert first_bad_node(x, v) == 5
    assert "at node 5 (1-based" in str(RunStopped("non-finite energy", 1e-3, node=first_bad_node(x, v)))
