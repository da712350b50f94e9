"""Guards during a run (issue 11, part 4): a collapsing stable step stops the run naming the element that sets it;
a NaN names the first node; a failed run's summary points at the last good frame."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

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


@pytest.mark.parametrize("damping", ["", ", deformation_damping: {rate: 1000.0}"])
def test_collapsing_step_names_the_element_and_keeps_the_last_good_frame(tmp_path, damping):
    """Requirement: when the stable step falls below min_dt_ratio x the step's first one, the run stops with exit 4
    and a message naming the element that sets the step; here the one element of the 100x stiffer section (its
    wave speed is 10x the others', so it alone sets the step; reference: the compiled section's element id), also
    when an effect whose bound is a share of the elements' steps (deformation damping) is the lowest bound. The
    summary's last good frame is earlier than the stop and holds finite displacements, and the stop happens once
    the step has fallen by 2 % (the collapse ratio asked), not before: the last history dt is within 2 % of the
    first (tolerance: the ratio itself)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import read_deck

    path = write_deck(tmp_path, TWO_MATERIALS.replace("min_dt_ratio: 0.98}", "min_dt_ratio: 0.98" + damping + "}"))
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


BAR = """title: bar pulled at one end
mesh:
  block: {size: [20, 2, 2], divisions: [10, 1, 1]}
materials:
  steel: {type: linear_elastic, density: 7.85e-9, youngs_modulus: 2.0e5, poisson_ratio: 0.0}
sections:
  - {material: steel, formulation: full}
boundary:
  - {type: fixed, nodes: xmin}
  - {type: velocity, nodes: xmax, dofs: [x], value: 100.0, amplitude: smooth}
steps:
  - {duration: 2.0e-4}
output: {frames: 4, history_points: 400}
checks:
  energy_balance: {max_error: 0.01, stop_above: 0.01}
"""


def _run_bar(tmp_path, step_factor: float, guard: bool = True):
    """The bar run by the engine with every element step multiplied by ``step_factor`` (1.5: past the exact
    critical step, central differences unstable) -> (result, history array, columns)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import read_deck
    from fdeck.engine import solver

    path = write_deck(tmp_path, BAR if guard else BAR.replace(", stop_above: 0.01", ""))
    deck, _, _ = read_deck(path)
    problem = compile_deck(deck, path.parent)
    for g in problem.groups:
        honest = g.stable_dt
        g.stable_dt = lambda honest=honest: step_factor * honest()
    res = solver.run(problem, solver.Sink())
    return res, np.array(res.history), res.columns


def test_created_energy_stops_the_run_before_it_blows_up(tmp_path):
    """Requirement: with checks.energy_balance.stop_above, a run that creates energy stops (status failed, cause
    'energy created') with finite state, long before it would blow up. The step is forced to 1.5x its estimate (past
    the exact critical step, which is the estimate on this nu = 0 bar: tests/test_stable_step.py), so the highest
    mode grows every cycle. References: (1) the same deck at the honest step completes with a balance error below
    1e-6 of the largest energy (central differences conserve energy to round-off; its first rows, at energies of
    1e-17 mJ, are round-off only and must not stop it); (2) the unstable deck without the guard runs on until the
    state is non-finite or an element inverts, later than the guarded stop."""
    res, hist, cols = _run_bar(tmp_path / "honest", 1.0)
    assert res.status == "completed", res.message
    i = {c: k for k, c in enumerate(cols)}
    scale = np.abs(hist[:, [i["kinetic_energy"], i["internal_energy"], i["external_work"]]]).max()
    assert np.abs(hist[:, i["energy_balance_error"]]).max() < 1e-6 * scale

    guarded, _, _ = _run_bar(tmp_path / "unstable", 1.5)
    assert guarded.status == "failed" and "energy created" in guarded.message, guarded.message
    assert np.isfinite(guarded.final_positions).all() and np.isfinite(guarded.final_velocities).all()
    free, _, _ = _run_bar(tmp_path / "unguarded", 1.5, guard=False)
    assert free.status == "failed" and "energy created" not in free.message, free.message
    assert free.t > guarded.t
