"""Tetrahedron punch decks (decks/forming/tetrahedron_*.yaml, MODELS.md 6.4): validation, tool files, and the
coarse deck's run (about 100 CPU-seconds on one thread with its selective mass, see the deck's header) checked against the punch
geometry, the energy the punch and the holder put in and the fibres' inextensibility."""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml

from helpers import DECKS, run_once_per_session

FORMING = DECKS / "forming"
TETRA = sorted(FORMING.glob("tetrahedron_*.yaml"))
COARSE = FORMING / "tetrahedron_coarse.yaml"
LIFT = 65.0  # punch travel [mm]: the tool files are written raised by it (make_tools)


def _cli(*args, timeout=900):
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-m", "fdeck.cli", *args], capture_output=True, text=True, env=env,
                          timeout=timeout)


def _block(path):
    return yaml.safe_load(path.read_text())["mesh"]["block"]


def test_decks_validate_and_info_names_tools_and_pairs():
    """Requirement: every tetrahedron deck validates (exit 0) and `fdeck info` prints the punch, the die and the
    force-driven holder, and one contact pair per tool whose blank-node count is one face of the block,
    (nx+1)(ny+1) (exact integer: the top face zmax meets punch and holder, the bottom face zmin the die)."""
    assert len(TETRA) == 3
    r = _cli("validate", *map(str, TETRA), timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    for path in TETRA:
        r = _cli("info", str(path), timeout=300)
        assert r.returncode == 0, r.stdout + r.stderr
        assert "tool punch: mesh 'tools/tetrahedron_punch_whole.stl', displacement 65 mm" in r.stdout
        assert "tool die: mesh 'tools/tetrahedron_die.stl', fixed" in r.stdout
        assert "tool holder: mesh 'tools/tetrahedron_holder.stl', force 800 N" in r.stdout
        nx, ny, nz = _block(path)["divisions"]
        face = (nx + 1) * (ny + 1)
        for tool in ("punch", "die", "holder"):
            m = re.search(rf"contact with tool '{tool}': (\d+) blank nodes", r.stdout)
            assert m and int(m.group(1)) == face, (path.name, tool, r.stdout)


def test_whole_punch_file_is_the_generator_punch():
    """Requirement: tools/tetrahedron_punch_whole.stl is the generator's tetrahedral punch with half=False (h = 4
    mm): same triangle count (exact), lowest point at the closed position + 65 mm and largest |y| = side/2 + radius
    + h (1e-4 mm: float32 STL), symmetric about y = 0 (so the half blank meets the same surface as the half punch,
    without its cap on the symmetry plane)."""
    import meshio

    from fdeck.physics.tools.generators import tetrahedron

    m = meshio.read(FORMING / "tools" / "tetrahedron_punch_whole.stl")
    p, t = tetrahedron(part="punch", half=False, h=4.0)
    assert len(m.cells_dict["triangle"]) == len(t)
    assert abs(m.points[:, 2].min() - (p[:, 2].min() + LIFT)) < 1e-4
    assert abs(m.points[:, 2].min() - (-60.0 + LIFT)) < 1e-4
    assert abs(np.abs(m.points[:, 1]).max() - (265.0 / 2 + 10.0 + 4.0)) < 1e-4
    assert abs(m.points[:, 1].min() + m.points[:, 1].max()) < 1e-4


def test_holder_file_is_the_die_flange_turned_over():
    """Requirement: tools/tetrahedron_holder.stl is generators.flange_holder of the generator's die (h = 4 mm): the
    die triangles lying on the flange plane z = 0 (exact count), every point at z = 0 (1e-6 mm: float32 STL), and
    every normal pointing down (-z to 1e-9: a holder presses from above), so the holder covers the flange up to
    where the die's entry radius starts and never the radius."""
    import meshio

    from fdeck.physics.tools.generators import flange_holder, tetrahedron

    p, t = tetrahedron(part="die", h=4.0)
    flat = (np.abs(p[t, 2]) <= 1e-9).all(axis=1)
    P, T = flange_holder(p, t)
    m = meshio.read(FORMING / "tools" / "tetrahedron_holder.stl")
    tri = m.cells_dict["triangle"]
    assert len(tri) == len(T) == int(flat.sum()) > 0
    assert np.abs(m.points[:, 2]).max() < 1e-6
    n = np.cross(m.points[tri[:, 1]] - m.points[tri[:, 0]], m.points[tri[:, 2]] - m.points[tri[:, 0]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    assert np.abs(n[:, 2] + 1.0).max() < 1e-9


# -- the coarse run ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def coarse_run(tmp_path_factory):
    out, r = run_once_per_session(tmp_path_factory, "tetrahedron_coarse", COARSE)
    rows = list(csv.DictReader(open(out / "history.csv")))
    hist = {k: np.array([float(row[k]) for row in rows]) for k in rows[0]}
    path = list(csv.DictReader(open(out / "path_symmetry_line.csv")))
    path = {k: np.array([float(row[k]) for row in path]) for k in path[0]}
    return r, hist, path, json.loads((out / "summary.json").read_text())


def _punch_profile(n=4001):
    """Lowest z [mm] of the punch along y = 0 at the end of travel (generator geometry, tetrahedron defaults), on
    x in [-120, 180] mm: (x, z) arrays, z = inf outside the footprint."""
    from fdeck.physics.tools.generators import tetra_lower_envelope

    x = np.linspace(-120.0, 180.0, n)
    z = tetra_lower_envelope(x, np.zeros_like(x), radius=10.0, apex_z=-50.0, side=265.0, core_height=120.0)
    return x, z


def test_coarse_run_energy_put_in_by_the_punch(coarse_run):
    """Requirement: the work of the punch and of the holder integrated from the history's force and displacement
    columns (trapezoid rule on the deck's 400 rows, independent of the ledger's own terms) equals kinetic + strain +
    contact energy + friction dissipation to 1 % of the work (the deck's energy_balance limit; measured 4.0e-3 on
    400 rows with the 800 N holder: the sampled force chatters between rows), and the energy_balance check passes."""
    r, h, _, s = coarse_run

    def trapezoid(f, u):
        return np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(u))])

    work = (trapezoid(h["tool_punch_force_z"], h["tool_punch_displacement_z"])
            + trapezoid(h["tool_holder_force_z"], h["tool_holder_displacement_z"]))
    held = h["kinetic_energy"] + h["strain_energy"] + h["contact_energy"] + h["friction_dissipation"]
    assert work[-1] > 0.0
    err = np.abs(held - work).max() / work[-1]
    assert err < 0.01, err
    assert [c for c in s["checks"] if c["name"] == "energy_balance"][0]["passed"]


def test_coarse_run_punch_force_starts_at_contact(coarse_run):
    """Requirement: the punch's force on the blank is exactly zero while its lowest point (5 mm - u above the
    flange) stays above the blank's top face (c0 + 2.54 mm) plus the law's clearance c0 = 0.1 mm, i.e. for
    u < 5 - 2.74 = 2.26 mm, and pushes down (F_z < 0) at full stroke (last history row: u = 65 mm to 0.05 mm, the
    stroke history decelerating to rest; the last row lies up to T/400 before the end)."""
    _, h, _, _ = coarse_run
    u, fz = -h["tool_punch_displacement_z"], h["tool_punch_force_z"]
    before = u < 5.0 - (0.1 + 2.54 + 0.1)
    assert before.sum() >= 5 and np.all(fz[before] == 0.0)
    assert abs(u[-1] - 65.0) < 0.05 and fz[-1] < 0.0


def test_coarse_run_blank_wraps_the_punch(coarse_run):
    """Requirement: along the symmetry line (path_symmetry_line.csv, mid-surface, y = 0) the formed blank (a) keeps
    its length, 600 mm, within 1 % (the warp fibres along x are three orders stiffer than shear and compaction);
    (b) reaches the punch apex: its lowest point lies at most 1.5 mm below the apex's depth -60 mm minus half the
    ply, 1.27 mm (clearance 0.1 mm and compaction: nothing pushes it deeper), and at most 7.6 mm above it: nodes
    20 mm apart straddling the apex (x = +-10) sit on the punch 7.1 mm above its lowest point (sphere r = 10 mm up
    to 57.5 deg, r (1 - cos 57.5) = 4.6 mm, then the face, 1.6 mm x tan 57.5 = 2.5 mm), and the element between
    them is straight, + 0.5 mm for the facets and the clearance (node-to-surface contact: the punch pokes between
    nodes, see the contact docs); (c) is at
    least as long below the flange (z < 0) as the punch's own profile below z = 0 there (a curve that stays
    outside a convex section and joins its two sides is no shorter than the section's boundary between them;
    2 % for the 20 mm chords cutting the 10 mm radii)."""
    _, _, p, _ = coarse_run
    xyz = np.column_stack([p["x"], p["y"], p["z"]])
    seg = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
    assert abs(seg.sum() - 600.0) < 0.01 * 600.0, seg.sum()
    assert -61.27 - 1.5 <= p["z"].min() <= -61.27 + 7.1 + 0.5, p["z"].min()
    # formed length below z = 0 (segments cut at z = 0)
    z0, z1 = p["z"][:-1], p["z"][1:]
    frac = np.where((z0 < 0) & (z1 < 0), 1.0, np.where((z0 < 0) ^ (z1 < 0), np.abs(np.minimum(z0, z1)) /
                                                          np.maximum(np.abs(z1 - z0), 1e-30), 0.0))
    formed = (seg * frac).sum()
    x, z = _punch_profile()
    below = z < 0.0
    xs, zs = x[below], z[below]
    # vertical closure from the last sample below 0 up to z = 0 at both ends: never longer than the true profile
    arc = np.hypot(np.diff(xs), np.diff(zs)).sum() - zs[0] - zs[-1]
    assert formed >= 0.98 * arc, (formed, arc)


def test_coarse_run_is_quasi_static(coarse_run):
    """Requirement (MODELS 6.4): kinetic / internal energy of the blank below 5 % after the first quarter of the
    run, recomputed from history.csv, and the run exits 0 (measured 0.0408 with the 800 N holder, one run; 0.0517
    with 200 N, which is why the holder is 800 N; 0.039 with the selective mass now in the deck: deck header)."""
    r, h, _, _ = coarse_run
    late = h["time"] >= 0.25 * h["time"][-1]
    ratio = (h["kinetic_energy"][late] / h["internal_energy"][late]).max()
    assert ratio < 0.05 and r.returncode == 0, (ratio, r.stdout[-2000:])
