"""Double-dome forming decks (decks/forming/double_dome_*.yaml): every deck validated, and the coarse 0/90 deck run
through the CLI (module fixture, one run of 62 708 cycles: 107 CPU-seconds on one core measured at load average 11
on 2 cores, about 80 at the 780 cycles per CPU-second of a quieter machine; default tier), its history and
frames checked against independent references: the energy conservation law, Newton's law on the force-driven
blank holder, contact kinematics (the punch's initial gap), the die geometry (draw-in) and the warp's tensile
stiffness (formed length along the symmetry line).
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys

import numpy as np
import pytest
import yaml

from tests.helpers import ROOT, run_once_per_session

DECKS = sorted((ROOT / "decks" / "forming").glob("double_dome_*.yaml"))
COARSE = ROOT / "decks" / "forming" / "double_dome_090_coarse.yaml"
GAP0 = 0.2     # punch's lowest point above the blank's top face at t = 0 [mm] (deck: offset -4.76 of 7.6 - 2.64)
C0 = 0.1       # exponential law clearance [mm]: no pressure while the gap exceeds c0


def _deck():
    return yaml.safe_load(COARSE.read_text())


def _run(deck, tmp_path_factory, name):
    out, r = run_once_per_session(tmp_path_factory, name, deck, timeout=600)
    rows = list(csv.DictReader(open(out / "history.csv")))
    h = {k: np.array([float(row[k]) for row in rows]) for k in rows[0]}
    return r, h, out


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return _run(COARSE, tmp_path_factory, "dd090")


@pytest.fixture(scope="module")
def run45(tmp_path_factory):
    return _run(COARSE.with_name("double_dome_45_coarse.yaml"), tmp_path_factory, "dd45")


def _passes_and_balances(run):
    """The run completed with every check passing (exit 0), and from the history columns, independent of the
    checks' code: kinetic + internal (which holds the contact energy) + damping + friction dissipation - external
    work - work of every tool on the blank (punch, die, holder) - the contacts' area work (the normal force law's
    own, ``physics/effects/contact.py``) - what the selective mass's following rigid modes changed in the kinetic
    energy (``mass_corotation_work``, where selective mass is on) stays below 1 % of the largest energy, and matches
    the solver's own error column to 1e-6 of that scale (the CSV's rounding)."""
    r, h, out = run
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed", r.stdout[-2000:] + r.stderr[-2000:]
    failed = [c["name"] for c in summary["checks"] if not c["passed"]]
    assert failed == [] and r.returncode == 0, (failed, r.stdout[-2000:])
    tools = [k for k in h if k.startswith("tool_work_")]
    assert sorted(tools) == ["tool_work_die", "tool_work_holder", "tool_work_punch"]
    bal = (h["kinetic_energy"] + h["internal_energy"] + h["damping_energy"] + h["friction_dissipation"]
           - h["external_work"] - sum(h[k] for k in tools) - h["contact_area_work"]
           - h.get("mass_corotation_work", 0.0))
    scale = max(np.abs(h["kinetic_energy"]).max(), np.abs(h["internal_energy"]).max())
    assert np.abs(bal).max() / scale < 0.01
    assert np.abs(bal - h["energy_balance_error"]).max() / scale < 1e-6


def _quasi_static(run):
    """kinetic / internal energy of the blank after the first quarter of the run (the published quasi-static
    criterion, MODELS 6.4), from the history columns; the added mass's kinetic energy (selective mass scaling) is
    part of the kinetic energy."""
    _, h, _ = run
    late = h["time"] >= 0.25 * h["time"][-1]
    return (h["kinetic_energy"][late] / np.maximum(h["internal_energy"][late], 1e-300)).max()


@pytest.mark.parametrize("size", ["coarse", pytest.param("full", marks=pytest.mark.nightly)])
def test_decks_validate(size):
    """Requirement: every double-dome deck passes `fdeck validate` (schema, names, sets, blank clear of the tools).
    The coarse decks in the default tier; the four full-size ones (up to 80 656 hexahedra, about 40 CPU-s of
    set-up) nightly."""
    assert len(DECKS) == 6
    decks = [d for d in DECKS if d.stem.endswith("_coarse") == (size == "coarse")]
    assert len(decks) == (2 if size == "coarse" else 4)
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "validate", *map(str, decks)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout.count(": ok") == len(decks), r.stdout


def test_coarse_run_conserves_energy(run):
    """Requirement: the coarse 0/90 deck completes with every check passing and balances its energy (see
    ``_passes_and_balances``)."""
    _passes_and_balances(run)


def test_coarse_run_is_quasi_static(run):
    """Requirement: kinetic / internal energy of the blank stays below 5 % after the first quarter of the run
    (measured 0.040 with the 800 N holder, 0.096 with the 100 N first chosen; 0.043 with the selective mass now in
    the deck: deck header)."""
    assert _quasi_static(run) < 0.05


def test_coarse_45_run_completes_quasi_statically_and_balances(run45):
    """Requirement: the coarse +-45 deck (the one-layer blank that used to invert an element 2.4 mm before closure
    with a 100 N holder) completes the full stroke with every check passing, its energy balanced as the 0/90 deck's
    and kinetic / internal below 5 % (measured 0.020 on the fibre-aligned lattice; 0.023 with the selective mass and
    0.019 without on the grid it used before: deck header)."""
    _passes_and_balances(run45)
    _, h, _ = run45
    assert -h["tool_punch_displacement_z"][-1] >= 0.99 * _deck()["tools"]["punch"]["motion"]["value"]
    assert _quasi_static(run45) < 0.05


def test_punch_force_zero_before_contact_and_pushing_after(run):
    """Requirement: the punch exerts no force while its gap to the blank exceeds the law's clearance c0 (the
    punch starts GAP0 = 0.2 mm above the blank: travel below GAP0 - c0 = 0.1 mm, minus 0.02 mm for the blank's
    own settling under the holder), and pushes the blank down (force on the blank along -z, below -1 N) over the
    last tenth of the stroke, where the blank is drawn into the 60 mm deep die; the punch follows the deck's
    tabular stroke history (linear interpolation of its knots, evaluated here with numpy at each row's time) to
    1e-9 of the stroke, and the last row (up to T/200 before the end, on the deceleration) has 99 % of it."""
    _, h, _ = run
    deck = _deck()
    stroke = deck["tools"]["punch"]["motion"]["value"]
    knots = np.array(deck["amplitudes"]["stroke"]["points"])
    travel = -h["tool_punch_displacement_z"]
    assert np.abs(travel - stroke * np.interp(h["time"], knots[:, 0], knots[:, 1])).max() < 1e-9 * stroke
    assert travel[-1] >= 0.99 * stroke
    before = travel < GAP0 - C0 - 0.02
    assert before.sum() >= 2
    assert np.abs(h["tool_punch_force_z"][before]).max() < 1e-9
    late = travel > 0.9 * travel.max()
    assert h["tool_punch_force_z"][late].max() < -1.0


def test_holder_presses_the_flange_with_its_force(run):
    """Requirement: the force-driven holder (mass M, force F along -z) presses the blank with F: Newton's law on the
    holder gives the time mean of its contact force over [t0, t1] as F - M (V1 - V0) / (t1 - t0), which over the
    middle half of the run (holder settled, flange under it) is F within M * 2 * 50 mm/s / (T/2) < 0.01 N; the
    force is sampled on history rows (T/200 apart) while it rings by about +-10 % around F, so the mean of ~100
    sampled rows is asserted to 5 % of F."""
    _, h, _ = run
    mo = _deck()["tools"]["holder"]["motion"]
    T = h["time"][-1]
    mid = (h["time"] >= 0.25 * T) & (h["time"] <= 0.75 * T)
    assert mid.sum() >= 50
    mean = h["tool_holder_force_z"][mid].mean()  # force of the holder on the blank: along -z
    assert mean == pytest.approx(-mo["value"], rel=0.05), mean
    assert np.abs(h["tool_holder_velocity"][mid]).max() < 50.0


def test_draw_in_matches_the_die_profile(run):
    """Requirement: along the symmetry line y = 0 the warp (x) is nearly inextensible, so the free edge's draw-in
    at the end is AT LEAST the extra length the formed blank needs over the die there: arc length of the die
    profile z(x, 0) (generators.double_dome_surface, independent of the run) minus its chord, x from 0 to 160 mm
    (past the flange entry). Lower bound only: the lobes beside the line pull more material in. Tolerance: the
    warp may stretch up to 1 % over the 160 mm (1.6 mm)."""
    import meshio

    from fdeck.physics.tools.generators import double_dome_surface

    _, h, out = run
    x = np.linspace(0.0, 160.0, 4001)
    z = double_dome_surface(x, np.zeros_like(x))
    ref = float(np.sum(np.hypot(np.diff(x), np.diff(z))) - (x[-1] - x[0]))
    assert ref > 1.0  # the die is not flat along y = 0
    frames = sorted(out.glob("double_dome_090_coarse_[0-9]*.vtu"))
    m0, m1 = meshio.read(frames[0]), meshio.read(frames[-1])
    edge = np.flatnonzero((np.abs(m0.points[:, 0] - 300.0) < 1e-6) & (np.abs(m0.points[:, 1]) < 1e-6))
    draw = -m1.point_data["displacement"][edge, 0].mean()
    assert draw >= ref - 0.01 * 160.0, (draw, ref)
    assert h["draw_in_x_max"][-1] >= draw - 1e-6  # the measure's largest edge draw-in covers this node's


def test_warp_and_weft_do_not_stretch_along_the_symmetry_lines(run):
    """Requirement: the formed length of the 300 mm material lines on the symmetry planes (path_symmetry_x/y.csv,
    current positions of the mid-surface points) does not exceed 300 mm by more than 1 %: the fibres along them
    are three orders stiffer in tension than the fabric in shear and compaction (3WEAVE preset), and the holder's
    100 N with friction 0.2 loads them far below 1 % strain. (Shorter is allowed: a dry fabric buckles in
    compression and the sampled polyline cuts the element corners.) And the line still reaches into the die: its
    lowest point lies below z = -20 mm (the die is 60 mm deep; the saddle at the centre 33 mm)."""
    _, _, out = run
    for name in ("symmetry_x", "symmetry_y"):
        rows = list(csv.DictReader(open(out / f"path_{name}.csv")))
        xyz = np.array([[float(r[k]) for k in "xyz"] for r in rows])
        length = np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum()
        assert length <= 300.0 * 1.01, (name, length)
        assert xyz[:, 2].min() < -20.0, (name, xyz[:, 2].min())
