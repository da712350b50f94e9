"""Formability outputs: shear angle along paths, the fibre table, draw-in, the wrinkle indicator, tools in frames.

Each quantity is checked against a closed form on a prescribed deformation (no solver run): the groups are updated
at positions x given by a formula, then the measure or table is read, so the reference is independent of the
dynamics and the tolerances only cover the discretisation stated in each test.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest

from fdeck.compile.errors import CompileError
from fdeck.compile.problem import compile_deck
from fdeck.deck.model import Deck
from fdeck.engine.effect import Effect
from fdeck.engine.rotation import Rotations
from fdeck.io.frames import open_series
from fdeck.io.tables import read_table
from fdeck.run import Outputs

pytestmark = pytest.mark.verification


def _compile(data):
    return compile_deck(Deck.model_validate(data), Path("."))


def _plate(size, h, output, material=None):
    return {"mesh": {"plate": {"size": list(size), "element_size": h}},
            "materials": {"cloth": material or {"type": "sm"}}, "sections": [{"material": "cloth"}],
            "steps": [{"duration": 0.01}], "output": output}


def _block(size, divisions, output):
    return {"mesh": {"block": {"size": list(size), "divisions": list(divisions)}},
            "materials": {"e": {"type": "linear_elastic", "density": 1e-9, "youngs_modulus": 1000.0,
                                "poisson_ratio": 0.3}},
            "sections": [{"material": "e", "elements": "all"}], "steps": [{"duration": 0.01}], "output": output}


def _update(problem, x):
    """Groups evaluated at positions x (shell directors at rest: the plate stays flat)."""
    if problem.rotations is not None:
        rot = Rotations(problem.rotations.d0, problem.rotations.nodes)
        for g in problem.groups:
            if g.rotational:
                g.bind(rot)
    for g in problem.groups:
        g.update(x, np.zeros_like(x))


# --------------------------------------------------------------------------------------------------------------------
# paths and the fibre table


def test_path_and_fibre_table_under_simple_shear(tmp_path):
    """Requirement: under a simple shear x = X + k Y e_x of a woven plate (warp along x, weft along y),
    path_<name>.csv gives the arc length, the reference point, the current point X + k Y e_x and the shear angle
    atan(k) of the element holding each sample; fibres.csv gives every element (1-based, mesh order) with its
    current centroid, warp e_x, weft (k, 1, 0)/sqrt(1 + k^2) and shear angle atan(k); a PNG is drawn beside the
    path. Tolerances: points and directions 1e-9 mm or 1e-9 (a bilinear element reproduces an affine map exactly,
    the rest is round-off of the Gauss-Newton location); shear angle 1e-6 deg (the law's angle from the same
    F, round-off)."""
    k = 0.4
    p = _compile(_plate((20.0, 10.0), 2.0, {
        "paths": [{"name": "diag", "points": [[1.0, 1.0, 0.0], [19.0, 9.0, 0.0], [19.0, 1.0, 0.0]], "samples": 41}],
        "fibre_table": True}))
    x = p.X.copy()
    x[:, 0] += k * p.X[:, 1]
    _update(p, x)
    out = Outputs(p, tmp_path, "t", lambda *a: None)
    out.tables_at_end(x)
    out.close()
    assert out.tables == ["path_diag.csv", "path_diag.png", "fibres.csv"]
    assert (tmp_path / "path_diag.png").stat().st_size > 1000

    t = read_table(tmp_path / "path_diag.csv")
    L1 = math.hypot(18.0, 8.0)
    assert t["arc_length"][-1] == pytest.approx(L1 + 8.0, abs=1e-12)
    np.testing.assert_allclose(t["x"], t["X"] + k * t["Y"], atol=1e-9)
    np.testing.assert_allclose(t["y"], t["Y"], atol=1e-9)
    np.testing.assert_allclose(t["distance"], 0.0, atol=1e-9)
    np.testing.assert_allclose(t["shear_angle"], math.degrees(math.atan(k)), atol=1e-6)
    # each sample lies in the element the table names: that element's reference centroid is within half a size
    f = read_table(tmp_path / "fibres.csv")
    conn = p.cells["quad"]
    centroid0 = p.X[conn].mean(axis=1)
    el = t["element"].astype(int) - 1
    assert np.all(np.abs(centroid0[el, 0] - t["X"]) <= 1.0 + 1e-9)
    assert np.all(np.abs(centroid0[el, 1] - t["Y"]) <= 1.0 + 1e-9)

    np.testing.assert_array_equal(f["element"], np.arange(1, len(conn) + 1))
    np.testing.assert_allclose(f["cx"], centroid0[:, 0] + k * centroid0[:, 1], atol=1e-9)
    np.testing.assert_allclose(np.stack([f["warp_x"], f["warp_y"], f["warp_z"]], 1),
                               np.broadcast_to([1.0, 0.0, 0.0], (len(conn), 3)), atol=1e-9)
    np.testing.assert_allclose(np.stack([f["weft_x"], f["weft_y"], f["weft_z"]], 1),
                               np.broadcast_to([k / math.hypot(1, k), 1 / math.hypot(1, k), 0.0], (len(conn), 3)),
                               atol=1e-9)
    np.testing.assert_allclose(f["shear_angle"], math.degrees(math.atan(k)), atol=1e-6)


def test_path_point_off_the_mesh_maps_to_the_nearest_element_with_its_distance(tmp_path):
    """Requirement: a path sample outside the blank takes the nearest element and reports its distance: a point
    3 mm beyond the edge x = 20 of a flat plate at rest is 3 mm away (1e-9 mm, round-off), current point on the
    edge."""
    p = _compile(_plate((20.0, 10.0), 2.0, {"paths": [{"name": "out", "points": [[18.0, 5.0, 0.0], [23.0, 5.0, 0.0]],
                                                       "samples": 6}]}))
    _update(p, p.X.copy())
    out = Outputs(p, tmp_path, "t", lambda *a: None)
    out.tables_at_end(p.X.copy())
    out.close()
    t = read_table(tmp_path / "path_out.csv")
    np.testing.assert_allclose(t["distance"], np.maximum(t["X"] - 20.0, 0.0), atol=1e-9)
    np.testing.assert_allclose(t["x"], np.minimum(t["X"], 20.0), atol=1e-9)


def test_path_through_the_thickness_is_the_layer_mean_of_a_shear_varying_through_it(tmp_path):
    """Requirement: ``through_thickness`` averages the shear angle over the blank's thickness. A 3WEAVE block
    20 x 10 x 4 mm, 4 layers (warp x, weft y), under x = X + (a + b Z) Y e_x: the weft at height Z turns by
    atan(a + b Z), so the through-thickness mean is (1/4) int_0^4 atan(a + b Z) dZ (closed form below), min and
    max the bottom and top layers' angles, and the plain path on the mid-plane (a layer interface) gives one of
    the two middle layers only. Tolerance 0.05 deg: an element reports its Gauss points' mean direction, which
    differs from the mean of the angle over its layer by about |d2 atan/dZ2| h^2 / 24 = 0.6 b^2 / 24 rad
    = 0.01 deg at most with h = 1 mm; a layer's centre value atan(a + b Z_c) differs from the layer mean by the
    same order, hence the same tolerance for min and max."""
    a, b = 0.2, 0.1
    deck = _block((20.0, 10.0, 4.0), (10, 5, 4), {"paths": [
        {"name": "mean", "points": [[3.0, 5.0, 2.0], [17.0, 5.0, 2.0]], "samples": 8,
         "through_thickness": {"axis": [0, 0, 1], "span": [0.0, 4.0], "samples": 8}},
        {"name": "plain", "points": [[3.0, 5.0, 2.0], [17.0, 5.0, 2.0]], "samples": 8}]})
    deck["materials"] = {"f": {"type": "3weave"}}
    deck["sections"] = [{"material": "f", "elements": "all", "formulation": "full"}]
    p = _compile(deck)
    x = p.X.copy()
    x[:, 0] += (a + b * p.X[:, 2]) * p.X[:, 1]
    _update(p, x)
    out = Outputs(p, tmp_path, "t", lambda *args: None)
    out.tables_at_end(x)
    out.close()
    t = read_table(tmp_path / "path_mean.csv")

    exact = math.degrees((_atan_primitive(a + 4 * b) - _atan_primitive(a)) / (4 * b))
    np.testing.assert_allclose(t["shear_angle"], exact, atol=0.05)
    np.testing.assert_allclose(t["shear_angle_min"], math.degrees(math.atan(a + 0.5 * b)), atol=0.05)
    np.testing.assert_allclose(t["shear_angle_max"], math.degrees(math.atan(a + 3.5 * b)), atol=0.05)
    plain = read_table(tmp_path / "path_plain.csv")["shear_angle"]
    middle = [math.degrees(math.atan(a + z * b)) for z in (1.5, 2.5)]
    assert all(min(abs(v - m) for m in middle) < 0.05 for v in plain)
    # each plain sample is one layer (19.3 or 24.2 deg, whichever element the tie on the interface picks), more than
    # 2 deg from the mean: what the option is for
    assert np.all(np.abs(plain - exact) > 2.0)


def _atan_primitive(g):
    """Antiderivative of atan(g) dg."""
    return g * math.atan(g) - 0.5 * math.log(1.0 + g * g)


def test_path_window_is_the_window_mean_of_a_shear_varying_along_the_path(tmp_path):
    """Requirement: ``window`` averages the shear angle over a square around every sample. A 3WEAVE block
    20 x 10 x 2 mm of 2 mm elements under x = X + c X (Y - 5) e_x: the weft turns by atan(c X), so along a path in
    x the window mean is (1/w) int atan(c X) dX over [X - w/2, X + w/2] = [P(c(X + w/2)) - P(c(X - w/2))] / (c w)
    (P the antiderivative of atan). Tolerance 0.05 deg: each element holds about its own centroid's angle, off the
    element mean by |d2 atan(cX)/dX2| h^2 / 24 <= 0.77 c^2 h^2 / 24 rad = 0.005 deg with h = 2 mm, c = 0.05/mm
    (the window's 8 x 8 points weight the elements by their overlap exactly when w is a multiple of h / 8). The
    samples lie on element centroids and boundaries; without the window the boundary samples are one element's
    angle, 1.9-2.6 deg from the window mean."""
    c, w = 0.05, 4.0
    xs = [5.0, 6.0, 9.0, 10.0, 13.0, 14.0]  # centroids of 2-mm elements and their shared faces, windows inside
    deck = _block((20.0, 10.0, 2.0), (10, 5, 1), {"paths": [
        {"name": "win", "points": [[5.0, 5.0, 1.0], [15.0, 5.0, 1.0]], "samples": 11, "window": w},
        {"name": "raw", "points": [[5.0, 5.0, 1.0], [15.0, 5.0, 1.0]], "samples": 11}]})
    deck["materials"] = {"f": {"type": "3weave"}}
    deck["sections"] = [{"material": "f", "elements": "all", "formulation": "full"}]
    p = _compile(deck)
    x = p.X.copy()
    x[:, 0] += c * p.X[:, 0] * (p.X[:, 1] - 5.0)
    _update(p, x)
    out = Outputs(p, tmp_path, "t", lambda *args: None)
    out.tables_at_end(x)
    out.close()
    t, raw = read_table(tmp_path / "path_win.csv"), read_table(tmp_path / "path_raw.csv")
    exact = np.array([math.degrees((_atan_primitive(c * (X + w / 2)) - _atan_primitive(c * (X - w / 2))) / (c * w))
                      for X in t["X"]])
    np.testing.assert_allclose(t["shear_angle"], exact, atol=0.05)
    assert set(xs) <= set(np.round(t["X"], 9))
    odd = np.isclose(t["X"] % 2.0, 0.0)  # samples on shared element faces: the raw path takes one element
    assert np.all(np.abs(raw["shear_angle"][odd] - exact[odd]) > 1.5)


def test_retable_from_the_last_frame_gives_the_tables_the_run_wrote(tmp_path):
    """Requirement: ``studies/forming.py retable`` rebuilds a deck's end-of-run tables from a finished run's last
    frame (for a path added after an hours-long run), or from an earlier frame (``frame``: the first is the rest
    state, zero shear to round-off). A 3WEAVE strip stretched and sheared by its end nodes, run
    with `fdeck run`'s engine: retable with the same deck gives the run's own path and fibre tables. Tolerance
    1e-9 (deg, mm): the frame stores the displacements in float64 (base64 binary VTU), so the only difference is
    the round-off of X + (x - X)."""
    from fdeck.deck.read import read_deck
    from fdeck.run import execute

    text = """
mesh: {block: {size: [20, 10, 2], divisions: [4, 2, 2]}}
materials: {f: {type: 3weave}}
sections: [{elements: all, material: f}]
boundary:
  - {type: fixed, nodes: xmin}
  - {type: velocity, nodes: xmax, dofs: [x], value: 200.0}
  - {type: velocity, nodes: xmax, dofs: [y], value: 300.0}
steps: [{duration: 0.002, mass_scaling: {factor: 100}}]
output:
  frames: 2
  paths: [{name: mid, points: [[1, 5, 1], [19, 5, 1]], samples: 9,
           through_thickness: {span: [0, 2], samples: 4}}]
  fibre_table: true
"""
    deck_path = tmp_path / "strip.yaml"
    deck_path.write_text(text)
    deck, _, _ = read_deck(deck_path)
    code, _ = execute(deck, tmp_path, tmp_path / "run", "strip", str(deck_path), echo=lambda *a: None)
    assert code == 0
    names = _forming_script().retable(deck_path, tmp_path / "run", tmp_path / "again")
    assert {"path_mid.csv", "fibres.csv"} <= set(names)
    for table in ("path_mid.csv", "fibres.csv"):
        ran, again = read_table(tmp_path / "run" / table), read_table(tmp_path / "again" / table)
        assert list(ran) == list(again)
        for k in ran:
            np.testing.assert_allclose(again[k], ran[k], rtol=0, atol=1e-9, err_msg=f"{table}: {k}")
    sheared = read_table(tmp_path / "run" / "path_mid.csv")["shear_angle"]
    assert np.abs(sheared).max() > 1.0  # the state compared is a deformed one, not the rest state
    # an earlier frame (--frame): the initial one is the undeformed blank, shear zero along the path
    _forming_script().retable(deck_path, tmp_path / "run", tmp_path / "first", frame=0)
    assert np.abs(read_table(tmp_path / "first" / "path_mid.csv")["shear_angle"]).max() < 1e-9
    # several frames at once (the deck compiled once): each the same table as alone, to the bit
    _forming_script().retable(deck_path, tmp_path / "run", tmp_path / "both", frame=[0, -1])
    for alone, k in (("first", 0), ("again", -1)):
        one, many = read_table(tmp_path / alone / "path_mid.csv"), read_table(tmp_path / f"both_{k}" / "path_mid.csv")
        assert all(np.array_equal(one[c], many[c]) for c in one), k


def test_retable_takes_every_set_whether_given_once_or_repeated_and_names_a_bad_one():
    """Requirement: ``retable --set A=1 --set B=2`` applies both settings, as ``--set A=1 B=2`` does (argparse's
    default would keep the last ``--set`` only, silently dropping a mesh change and running a 3 mm frame on the 5 mm
    mesh's deck). Exact: the parsed list is the one given."""
    ap = _forming_script().parser()
    given = ["mesh.block.divisions=[100,100,4]", "output.paths.0.window=5.0", "output.paths.1.window=5.0"]
    repeated = ap.parse_args(["retable", "d.yaml", "run", "out"] + [w for g in given for w in ("--set", g)])
    once = ap.parse_args(["retable", "d.yaml", "run", "out", "--set"] + given)
    assert repeated.set == once.set == given
    # a setting that leads nowhere is named, not a traceback (checked before any frame is read)
    deck = Path(__file__).parents[1] / "decks" / "forming" / "tetrahedron_coarse.yaml"
    with pytest.raises(SystemExit, match="output.paths.9"):
        _forming_script().retable(deck, "no_such_run", "no_such_out", {"output.paths.9": 1})


def test_path_deck_errors_are_located():
    """Requirement: a path with coinciding corners or a name that is not a file name part, or two paths of one
    name, is a located validation error."""
    from pydantic import ValidationError

    for paths, where in [([{"name": "a", "points": [[0, 0, 0], [0, 0, 0]]}], "points 0 and 1 coincide"),
                         ([{"name": "a/b", "points": [[0, 0, 0], [1, 0, 0]]}], "pattern"),
                         ([{"name": "a", "points": [[0, 0, 0], [1, 0, 0]]}] * 2, "path names repeated"),
                         ([{"name": "a", "points": [[0, 0, 0], [1, 0, 0]],
                            "through_thickness": {"span": [1.0, 1.0]}}], "two different coordinates"),
                         ([{"name": "a", "points": [[0, 0, 0], [1, 0, 0]],
                            "through_thickness": {"axis": [0, 0, 0], "span": [0.0, 1.0]}}], "zero vector"),
                         ([{"name": "a", "points": [[0, 0, 0], [0, 0, 1]], "window": 2.0}], "thickness axis"),
                         ([{"name": "a", "points": [[0, 0, 0], [1, 0, 0]], "window": 0.0}], "greater than 0")]:
        with pytest.raises(ValidationError) as info:
            Deck.model_validate(_plate((20.0, 10.0), 2.0, {"paths": paths}))
        assert where in str(info.value) and "output" in str(info.value)


# --------------------------------------------------------------------------------------------------------------------
# draw-in


def test_draw_in_of_a_uniform_radial_contraction():
    """Requirement: under x = X - e (X - C)_inplane + w e_z (a uniform in-plane contraction by e towards the centre
    C plus any lift w along the axis), the draw-in of a node at in-plane distance r from C is e r: the mean and the
    max over the edge set are e mean(r) and e max(r) (1e-12 mm: the closed form is exact; round-off only)."""
    p = _compile(_plate((20.0, 10.0), 2.0, {"measures": [
        {"type": "draw_in", "name": "din", "nodes": "xmax", "axis": "z"}]}))
    (m,) = p.measures
    assert m.columns == ["din_mean", "din_max"]
    C = np.array([10.0, 5.0, 0.0])
    e, w = 0.05, 3.0
    x = p.X.copy()
    x[:, :2] -= e * (p.X[:, :2] - C[:2])
    x[:, 2] += w * (1 + p.X[:, 0] / 20)
    r = np.linalg.norm(p.X[p.node_sets["xmax"], :2] - C[:2], axis=1)
    mean, mx = m.evaluate(x, None)
    assert mean == pytest.approx(e * r.mean(), abs=1e-12)
    assert mx == pytest.approx(e * r.max(), abs=1e-12)


def test_draw_in_node_on_the_axis_is_a_located_error():
    """Requirement: an edge node on the axis through the centre has no inward direction: a CompileError at the
    measure's `nodes`."""
    with pytest.raises(CompileError) as info:
        _compile(_plate((20.0, 10.0), 2.0, {"measures": [
            {"type": "draw_in", "name": "din", "nodes": "xmax", "centre": [20.0, 0.0, 5.0]}]}))
    assert info.value.problems[0][0] == ("output", "measures", 0, "nodes")


# --------------------------------------------------------------------------------------------------------------------
# wrinkles

RHO, R, A, WAVE = 100.0, 8.0, 0.3, 4.0  # sphere radius, patch radius, ripple amplitude, ripple wavelength R / 2 [mm]


def _cases():
    shell = _plate((60.0, 60.0), 1.0, {"measures": [
        {"type": "wrinkles", "name": "wr", "nodes": "all", "radius": R, "regions": ["middle"]}]})
    hexa = _block((60.0, 60.0, 4.0), (60, 60, 2), {"measures": [
        {"type": "wrinkles", "name": "wr", "nodes": "zmax", "radius": R, "regions": ["middle"]}]})
    for d in (shell, hexa):  # a region away from the edges, where the patches are whole discs
        d["mesh"]["node_sets"] = {"middle": {"box": [[15.0, 15.0, -10.0], [45.0, 45.0, 10.0]]}}
    return {"shell": shell, "hex top face": hexa}


@pytest.fixture(scope="module", params=["shell", "hex top face"])
def wrinkle_problem(request):
    return _compile(_cases()[request.param])


def _cap(X, shape):
    """Positions of a sphere cap (radius RHO) or a paraboloid of the same apex curvature over the 60 x 60 mm blank."""
    x = X.copy()
    r2 = ((X[:, :2] - 30.0) ** 2).sum(axis=1)
    x[:, 2] += RHO - np.sqrt(RHO**2 - r2) if shape == "sphere" else r2 / (2 * RHO)
    return x


@pytest.mark.parametrize("shape", ["sphere", "paraboloid"])
def test_wrinkle_indicator_of_a_smooth_cap_is_below_the_quartic_remainder(wrinkle_problem, shape):
    """Requirement: a smoothly doubly-curved surface scores about zero: on a sphere cap of radius rho = 100 mm (and a
    paraboloid of the same apex curvature), patches of R = 8 mm, every node's value is below R^4 / (8 rho^3) =
    5.1e-4 mm, the size of the quartic term the quadric cannot follow (module docstring; measured 0.9e-4 on the
    sphere). The paraboloid's curvature falls off towards the corners (slope 0.42 there), which adds quartic terms
    of the same order in the tilted frame: bound doubled to 1.0e-3 mm for it (measured 6.5e-4 at the corners,
    1.0e-4 in the middle region)."""
    (m,) = wrinkle_problem.measures
    vals = dict(zip(m.columns, m.evaluate(_cap(wrinkle_problem.X, shape), None)))
    assert set(vals) == {"wr_max", "wr_p99", "wr_middle_max", "wr_middle_p99"}
    bound = R**4 / (8 * RHO**3) * (1.0 if shape == "sphere" else 2.0)
    assert 0.0 <= vals["wr_max"] < bound
    assert 0.0 <= vals["wr_middle_max"] < R**4 / (8 * RHO**3)


def test_wrinkle_indicator_of_a_ripple_is_its_amplitude(wrinkle_problem):
    """Requirement: a ripple A sin(2 pi y / lambda) of amplitude A = 0.3 mm and wavelength lambda = R / 2 = 4 mm
    added to the sphere cap scores A: max and 99th percentile within 5 % of A over the whole surface and over the
    middle region (nodes sit on the crests, 1 mm spacing; the quadric fit over a patch 4 wavelengths wide takes in
    a few percent of the ripple, measured 0.97-0.99 A; half-disc patches at the edges take in more, hence the
    99th percentile rather than the minimum); the point field `wrinkle` is NaN off the surface and equals the
    per-node values on it."""
    p = wrinkle_problem
    (m,) = p.measures
    x = _cap(p.X, "sphere")
    x[:, 2] += A * np.sin(2 * np.pi * p.X[:, 1] / WAVE)
    vals = dict(zip(m.columns, m.evaluate(x, None)))
    for c in ("wr_max", "wr_p99", "wr_middle_max", "wr_middle_p99"):
        assert vals[c] == pytest.approx(A, rel=0.05), c
    field = m.point_fields(x)["wrinkle"]
    on = np.zeros(len(p.X), bool)
    on[m.nodes] = True
    assert np.all(np.isnan(field[~on])) and np.nanmax(field[on]) == vals["wr_max"]


def test_a_measure_field_per_element_is_the_largest_at_its_nodes():
    """Requirement: the cell field ``wrinkle_element`` (``run.cell_max``) is, element by element, the largest finite
    value of the nodal field at the element's nodes, NaN where all are NaN, over cell types in order: checked
    exactly (a max picks one of the values) against a loop over the elements on a hexahedron and a quad block."""
    from fdeck.run import cell_max

    rng = np.random.default_rng(5)
    field = rng.uniform(0.0, 1.0, 12)
    field[[0, 1, 2, 3, 4, 5, 6, 7]] = np.nan  # the hexahedron's nodes: all NaN
    field[9] = np.nan
    cells = {"hexahedron": np.array([[0, 1, 2, 3, 4, 5, 6, 7]]), "quad": np.array([[8, 9, 10, 11], [9, 10, 11, 0]])}
    got = cell_max(field, cells)
    expected = [np.nan] + [max(v for v in field[c] if np.isfinite(v)) for c in cells["quad"]]
    np.testing.assert_array_equal(got, expected)


def test_frames_carry_the_wrinkle_indicator_per_element(wrinkle_problem, tmp_path):
    """Requirement: a run's frame holds the nodal ``wrinkle`` and, per element, ``wrinkle_element``, the largest
    finite nodal value at the element's nodes (NaN where all are NaN), aligned with the frame's cells: a frame
    written by ``run.Outputs`` for the rippled cap (shell plate, and hexahedra whose top face is the surface) and
    read back with meshio, checked exactly against a loop over the cells (a max picks one of the values)."""
    import meshio

    from fdeck.run import Outputs

    p = wrinkle_problem
    x = _cap(p.X, "sphere")
    x[:, 2] += A * np.sin(2 * np.pi * p.X[:, 1] / WAVE)
    out = Outputs(p, tmp_path, "b", progress=None)
    out.frame(0.0, x, np.zeros_like(x))
    for series in out.series:
        series.close()
    mesh = meshio.read(next(tmp_path.glob("b_00000.vtu")))
    node = mesh.point_data["wrinkle"]
    cell = np.concatenate(mesh.cell_data["wrinkle_element"])
    conn = np.concatenate([block.data for block in mesh.cells])
    expected = [np.nanmax(node[c]) if np.isfinite(node[c]).any() else np.nan for c in conn]
    assert np.isfinite(cell).sum() > 0 and np.isnan(cell).sum() == np.isnan(expected).sum()
    np.testing.assert_array_equal(cell, expected)


def test_wrinkle_radius_too_small_is_a_located_error():
    """Requirement: a patch radius holding fewer than 9 nodes anywhere is a CompileError at `radius`."""
    data = _plate((10.0, 10.0), 2.0, {"measures": [{"type": "wrinkles", "name": "wr", "nodes": "all",
                                                     "radius": 2.5}]})
    with pytest.raises(CompileError) as info:
        _compile(data)
    assert info.value.problems[0][0] == ("output", "measures", 0, "radius")


# --------------------------------------------------------------------------------------------------------------------
# tool surfaces in the frame series


class MovingTriangle(Effect):
    """A fake tool: one triangle translated by (0, 0, -t) [mm at t s]."""

    name = "fake"
    P0 = np.array([[0.0, 0.0, 2.0], [1.0, 0.0, 2.0], [0.0, 1.0, 2.0]])

    def __init__(self):
        self.t = 0.0

    def surfaces(self):
        return [("punch", self.P0 - [0.0, 0.0, self.t], np.array([[0, 1, 2]]))]


def test_tool_surfaces_are_written_beside_the_blank_every_frame(tmp_path):
    """Requirement: an effect's surfaces go into every frame as their own block: VTU frames
    <name>_punch_NNNNN.vtu listed in the .pvd with part 1 at the blank's times, and a temporal collection of the
    tool in the .xdmf; every frame opens with meshio and VTK, the tool's points move exactly as given (round trip
    exact: binary float64), and meshio's XDMF reader still reads the blank; the default Effect has no surface."""
    import vtk
    from vtk.util.numpy_support import vtk_to_numpy

    assert Effect().surfaces() == []
    X = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    cells = {"quad": np.array([[0, 1, 2, 3]])}
    tool = MovingTriangle()
    times = [0.0, 0.25, 0.5]
    series = open_series(["vtu", "xdmf"], tmp_path, "b", X, cells)
    for t in times:
        tool.t = t
        for s in series:
            s.write(t, {"displacement": np.zeros((4, 3))}, None, surfaces=tool.surfaces())
    entries = [(float(e.get("timestep")), e.get("part"), e.get("file"))
               for e in ET.parse(tmp_path / "b.pvd").getroot().iter("DataSet")]
    assert entries == [e for k, t in enumerate(times)
                       for e in ((t, "0", f"b_{k:05d}.vtu"), (t, "1", f"b_punch_{k:05d}.vtu"))]
    reader = vtk.vtkXMLUnstructuredGridReader()
    for k, t in enumerate(times):
        expected = MovingTriangle.P0 - [0.0, 0.0, t]
        m = meshio.read(tmp_path / f"b_punch_{k:05d}.vtu")
        np.testing.assert_array_equal(m.points, expected)
        np.testing.assert_array_equal(m.cells_dict["triangle"], [[0, 1, 2]])
        reader.SetFileName(str(tmp_path / f"b_punch_{k:05d}.vtu"))
        reader.Update()
        np.testing.assert_array_equal(vtk_to_numpy(reader.GetOutput().GetPoints().GetData()), expected)
        assert meshio.read(tmp_path / f"b_{k:05d}.vtu").points.shape == (4, 3)
    with meshio.xdmf.TimeSeriesReader(tmp_path / "b.xdmf") as r:
        points, blocks = r.read_points_cells()
        assert r.num_steps == 3 and blocks[0].type == "quad"
        np.testing.assert_array_equal(points, X)
    xr = vtk.vtkXdmfReader()
    xr.SetFileName(str(tmp_path / "b.xdmf"))
    for t in times:
        xr.UpdateTimeStep(t)
        out = xr.GetOutputDataObject(0)
        blocks = {out.GetMetaData(i).Get(vtk.vtkCompositeDataSet.NAME()): out.GetBlock(i)
                  for i in range(out.GetNumberOfBlocks())}
        assert set(blocks) == {"b", "punch"}
        np.testing.assert_array_equal(vtk_to_numpy(blocks["punch"].GetPoints().GetData()),
                                      MovingTriangle.P0 - [0.0, 0.0, t])
        np.testing.assert_array_equal(vtk_to_numpy(blocks["b"].GetPoints().GetData()), X)


def _forming_script():
    import importlib.util

    spec = importlib.util.spec_from_file_location("forming", Path(__file__).parents[1] / "studies" / "forming.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_mirror_and_ellipticity_diagnostics_of_written_frames(tmp_path):
    """Requirement: ``studies/forming.py mirror`` measures how far a full model's shear field is from mirror symmetry
    about y = 0, ``ellipticity`` counts the elements whose law has lost strong ellipticity at their centre, and
    ``render`` draws the frame it is asked for.
    Frames written by fdeck's own series writer over a 3WEAVE block 20 x 20 x 2 mm (y from -10 to 10): an odd
    shear field gamma = 10 sign(y) (x + 1) deg is mirror-symmetric (0 to round-off), an even one of the same size
    differs by 2 |gamma| = 20 (x + 1) deg at most (closed forms). Displacements of a uniform warp compression: the
    law's stiffness against the warp turning vanishes at Hencky strain -K_ps0 / (2 ratio K_L1) = -0.370 at rest
    (test_fabric_hyper), so stretch 0.65 (e = -0.431) loses it in every element and 0.75 (e = -0.288) in none."""
    p = _compile(_block((20.0, 20.0, 2.0), (4, 4, 1), {}))
    X = p.X - np.array([0.0, 10.0, 0.0])
    conn = p.cells["hexahedron"]
    c = X[conn].mean(axis=1)
    odd = 10.0 * np.sign(c[:, 1]) * (c[:, 0] + 1.0)
    even = 10.0 * (c[:, 0] + 1.0)
    series = open_series(["vtu"], tmp_path, "b", X, {"hexahedron": conn})
    zero = np.zeros_like(X)
    for t, (u, g) in enumerate([(zero, odd), (zero, even), (X * [-0.35, 0, 0], odd), (X * [-0.25, 0, 0], odd)]):
        for s in series:
            s.write(float(t), {"displacement": u}, {"shear_angle": g})
    for s in series:
        s.close()
    forming = _forming_script()
    sym = forming.mirror(tmp_path)
    assert sym[0][0] < 1e-9 and sym[1][0] == pytest.approx(2 * np.abs(even).max(), rel=1e-9)
    assert forming.ellipticity(tmp_path, [0, 2, 3]) == [(0, 16), (16, 16), (0, 16)]
    # `render --frame K` draws frame K (here the even field, read back exactly), the last frame by default; a
    # colour range changes the picture, not the field
    drawn = forming.render(tmp_path, tmp_path / "even.png", frame=1, limits=(-30.0, 30.0))
    assert (drawn["min"], drawn["max"]) == (even.min(), even.max())
    last = forming.render(tmp_path, tmp_path / "last.png")
    assert (last["min"], last["max"]) == (odd.min(), odd.max()) and (tmp_path / "even.png").stat().st_size > 0


def test_row_alternation_measure_against_closed_forms(tmp_path):
    """Requirement: ``studies/forming.py rows`` gives, for an element-wise path table (two samples per element
    column, as the tetrahedron decks write), the second difference of the per-column shear: exactly 4 A for a
    field alternating +-A from column to column, exactly 2 c h^2 for the quadratic c s^2 on columns of length h
    (a second difference of a quadratic is exact), and splits the two at the arc length asked for. Exact
    arithmetic on the written table: tolerance 1e-9."""
    script = _forming_script()
    h, A, c = 10.0, 7.0, 0.01
    s = np.arange(0.0, 200.0, 5.0)  # two samples per 10 mm column
    col = np.floor(s / h)
    gamma = np.where(s < 100.0, 20.0 + A * (-1.0) ** col, c * (col * h) ** 2)
    rows = "\n".join(f"{a},{e:d},{g:.17g}" for a, e, g in zip(s, (2 * col).astype(int), gamma))
    (tmp_path / "path_p.csv").write_text("arc_length,element,shear_angle\n" + rows + "\n")
    near_rms, near_max, far_rms = script.rows("p", tmp_path, until=80.0)
    assert abs(near_rms - 4.0 * A) < 1e-9 and abs(near_max - 4.0 * A) < 1e-9
    far = script.rows("p", tmp_path, until=110.0)[2]  # columns 12..18: the quadratic alone
    assert abs(far - 2.0 * c * h ** 2) < 1e-9


def test_flange_waves_tell_a_resolved_wave_from_node_scale_scatter(tmp_path):
    """Requirement: ``studies/forming.py waves`` (the sm/ts square-tube comparison, README) reports, along a line of
    nodes, the rms and the dominant wavelength of the out-of-plane profile (less its straight-line fit) and the share
    of its variance at wavelengths below three node spacings. A 2.5 mm quad strip 80 mm long (33 nodes per line),
    a tilt 0.01 x added to both profiles (removed by the fit):
    * a wave A sin(2 pi x / 20 mm), A = 0.3 mm: rms within 5 % of A / sqrt(2) (measured -3 %: four periods and an
      end node, of which the straight-line fit takes a little), wavelength within 5 % of 20 mm (the transform's
      period is 33 spacings, 82.5 mm, whose 4th harmonic is 20.6 mm), short share below 1 % (measured 0.85 %,
      leakage of the line's unmatched ends);
    * a node-to-node zig-zag +-A: rms within 1 % of A (measured -0.05 %), short share above 0.95 (measured 0.964;
      the odd node count leaks a little to longer wavelengths);
    * a line asked for between rows takes the nearest row; the dominant wavelength is exactly the transform's
      harmonic 33 x 2.5 / 4 mm (to round-off)."""
    h, n = 2.5, 33
    X = np.array([[i * h, j * h, 0.0] for j in range(2) for i in range(n)])
    quads = np.array([[i, i + 1, n + i + 1, n + i] for i in range(n - 1)])
    x0 = X[:, 0]
    profiles = {"wave": 0.3 * np.sin(2 * np.pi * x0 / 20.0), "zigzag": 0.3 * (-1.0) ** np.round(x0 / h)}
    forming = _forming_script()
    out = {}
    for name, dz in profiles.items():
        series = open_series(["vtu"], tmp_path / name, "b", X, {"quad": quads})
        u = np.zeros_like(X)
        u[:, 2] = dz + 0.01 * x0
        for s in series:
            s.write(0.0, {"displacement": u}, None)
            s.close()
        (out[name],) = forming.waves(tmp_path / name, [0.0], 0.0)
    w, z = out["wave"], out["zigzag"]
    assert w["nodes"] == z["nodes"] == n
    assert w["rms"] == pytest.approx(0.3 / np.sqrt(2), rel=0.05) and w["wavelength"] == pytest.approx(20.0, rel=0.05)
    assert w["wavelength"] == pytest.approx(n * h / 4, rel=1e-12)  # the transform's 4th harmonic, 82.5 / 4 mm
    assert forming.waves(tmp_path / "wave", [1.0], 0.0) == [w]  # y = 1 mm: the nearest row of nodes, y = 0
    assert w["short_share"] < 0.01
    assert z["rms"] == pytest.approx(0.3, rel=0.01) and z["short_share"] > 0.95


def test_energies_integrate_each_fabric_term_over_the_reference_volume(tmp_path):
    """Requirement: ``studies/forming.py energies`` (the split of a forming run's strain energy by law term, README)
    gives, per energy density of a hexahedral blank's frame, its integral over the reference volume. A 3WEAVE F-bar
    block on the fibre-aligned lattice (diamonds and, along its edges, collapsed hexahedra: elements of two
    volumes, so volumes taken from another mesh reading or in another element order fail) at a
    prescribed deformation that loads every term (warp and weft stretch, compaction, in-plane and transverse shear,
    a bend): the integral of ``strain_energy_density`` against the engine's own quadrature, sum over elements and
    points of w psi, to round-off (1e-12 relative: the same numbers summed in another order); the law's six terms
    against that total to 1e-12 (the law is a sum of them); the initial frame's energies are zero, and the same."""
    data = {"mesh": {"block": {"size": [10.0, 10.0, 2.54], "divisions": [4, 4, 4], "lattice": "diagonal"}},
            "materials": {"f": {"type": "3weave"}}, "sections": [{"material": "f", "formulation": "fbar"}],
            "steps": [{"duration": 0.01}]}
    problem = _compile(data)
    X = problem.X
    x = X + np.stack([0.02 * X[:, 0] + 0.15 * X[:, 1] + 0.05 * X[:, 2] + 0.01 * X[:, 0] * (X[:, 2] - 1.27),
                      0.015 * X[:, 1] + 0.04 * X[:, 2], -0.08 * (X[:, 2]) - 0.004 * X[:, 0] ** 2], axis=1)
    _update(problem, x)
    (g,) = problem.groups
    fields = g.cell_fields()
    conn = {"hexahedron": g.conn}
    series = open_series(["vtu"], tmp_path / "run", "b", X, conn)
    for s in series:
        s.write(0.0, {"displacement": np.zeros_like(X)}, {k: np.zeros_like(v) for k, v in fields.items()})
        s.write(1.0, {"displacement": x - X}, fields)
        s.close()
    forming = _forming_script()
    (first,), (last,) = forming.energies([tmp_path / "run"], 0), forming.energies([tmp_path / "run"])
    total = float(np.sum(g.w * g.psi))
    assert len(np.unique(np.round(g.V0, 9))) == 2  # the lattice's diamonds and halves
    assert last["strain_energy_density"] == pytest.approx(total, rel=1e-12) and total > 0
    terms = [k for k in last if k.startswith("psi_")]
    assert len(terms) == 6 and min(last[k] for k in terms) > 0  # every term loaded
    assert sum(last[k] for k in terms) == pytest.approx(total, rel=1e-12)
    assert first.keys() == last.keys() and not any(first.values())


@pytest.mark.parametrize("formulation", ["fbar", "ans_tbar", "sm"])
def test_named_cell_fields_equal_the_full_output(formulation):
    """Requirement: a group asked for some cell fields only (``cell_fields(idx, names)``: the history's
    ``element_average`` measures and the path tables ask for one, every row) returns those fields with the same
    bits as the full output at a subset of elements, and leaves out the stress it was not asked for (the saving).
    A 3WEAVE block (F-bar, ``ans_tbar``) and an ``sm`` plate, sheared and stretched so every field is non-zero."""
    if formulation == "sm":
        problem = _compile(_plate((20.0, 10.0), 2.5, {}))
    else:
        problem = _compile({"mesh": {"block": {"size": [10.0, 10.0, 2.54], "divisions": [4, 4, 2]}},
                            "materials": {"f": {"type": "3weave"}},
                            "sections": [{"material": "f", "formulation": formulation}],
                            "steps": [{"duration": 0.01}]})
    X = problem.X
    x = X + np.stack([0.02 * X[:, 0] + 0.15 * X[:, 1], 0.015 * X[:, 1], -0.01 * X[:, 2]], axis=1)
    _update(problem, x)
    (g,) = problem.groups
    idx = np.arange(1, len(g.conn), 3)
    full = g.cell_fields(idx)
    for names in [("shear_angle",), ("stress",), ("shear_angle", "J")]:
        part = g.cell_fields(idx, names)
        for name in names:
            assert np.array_equal(part[name], full[name]), (names, name)
        assert ("stress" in part) == ("stress" in names)
    assert np.abs(full["shear_angle"]).min() > 1.0  # every element sheared: not a comparison of zeros
