"""Double-dome forming decks (decks/forming/double_dome_*.yaml): the coarse 0/90 deck run through the CLI, its
history checked against independent references (energy conservation, contact kinematics, the die geometry).

One run of about 2 minutes on one core (module fixture), in the nightly tier (`pytest -m nightly`): over CI's
budget, and the coarse deck does not yet pass its quasi-static check (see the xfail); every deck is validated in
the default run.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.helpers import ROOT

DECKS = sorted((ROOT / "decks" / "forming").glob("double_dome_*.yaml"))
COARSE = ROOT / "decks" / "forming" / "double_dome_090_coarse.yaml"
GAP0 = 0.2     # punch's lowest point above the blank's top face at t = 0 [mm] (deck: offset -4.76 of 7.6 - 2.64)
C0 = 0.1       # exponential law clearance [mm]: no pressure while the gap exceeds c0


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("dd090")
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(COARSE), "-o", str(out)], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=600)
    rows = list(csv.DictReader(open(out / "history.csv")))
    h = {k: np.array([float(row[k]) for row in rows]) for k in rows[0]}
    return r, h, out


def test_decks_validate():
    """Requirement: every double-dome deck passes `fdeck validate` (schema, names, sets, blank clear of the tools)."""
    assert len(DECKS) == 6
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "validate", *map(str, DECKS)], cwd=ROOT,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.nightly
def test_coarse_runs_to_the_end_with_energy_conserved(run):
    """Requirement: the coarse 0/90 deck completes (exit 0, or 3 for a failed check only) and its energy balance,
    recomputed from the history columns (kinetic + internal (which holds the contact energy) + damping + friction
    dissipation - external work - work of the tools on the blank), stays below 1 % of the largest energy: the
    conservation law, independent of the solver's own error column (which it must also match to 1e-6 of the
    scale, rounding of the CSV)."""
    r, h, _ = run
    assert r.returncode in (0, 3), r.stdout[-2000:] + r.stderr[-2000:]
    bal = (h["kinetic_energy"] + h["internal_energy"] + h["damping_energy"] + h["friction_dissipation"]
           - h["external_work"] - h["tool_work_punch"] - h["tool_work_die"])
    scale = max(np.abs(h["kinetic_energy"]).max(), np.abs(h["internal_energy"]).max())
    assert np.abs(bal).max() / scale < 0.01
    assert np.abs(bal - h["energy_balance_error"]).max() / scale < 1e-6


@pytest.mark.nightly
def test_punch_force_zero_before_contact_and_pushing_after(run):
    """Requirement: the punch exerts no force while its gap to the blank exceeds the law's clearance c0 (the
    punch starts GAP0 = 0.2 mm above the blank: travel below GAP0 - c0 = 0.1 mm, minus 0.02 mm for the blank's
    own motion being nil before contact), and pushes the blank down (force on the blank along -z, below -1 N) over
    the last tenth of the stroke, where the blank is drawn into the 60 mm deep die."""
    _, h, _ = run
    travel = -h["tool_punch_displacement_z"]
    before = travel < GAP0 - C0 - 0.02
    assert before.sum() >= 2
    assert np.abs(h["tool_punch_force_z"][before]).max() < 1e-9
    late = travel > 0.9 * travel.max()
    # history rows lie T/200 apart and the punch ends at about 270 mm/s: the last row may miss up to 0.4 mm
    assert travel.max() == pytest.approx(60.24, abs=1.0)
    assert h["tool_punch_force_z"][late].max() < -1.0


@pytest.mark.nightly
def test_draw_in_matches_the_die_profile(run):
    """Requirement: along the symmetry line y = 0 the warp (x) is nearly inextensible, so the free edge's draw-in
    at the end is AT LEAST the extra length the formed blank needs over the die there: arc length of the die
    profile z(x, 0) (generators.double_dome_surface, independent of the run) minus its chord, x from 0 to 160 mm
    (past the flange entry). Lower bound only: the lobes beside the line pull more material in (measured 19 mm
    against 8.3 mm). Tolerance: the warp may stretch up to 1 % over the 160 mm (1.6 mm)."""
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
    assert draw >= ref - 0.01 * 160.0
    assert h["draw_in_x_max"][-1] >= draw - 1e-6  # the measure's largest edge draw-in covers this node's


@pytest.mark.nightly
@pytest.mark.xfail(strict=True, reason="coarse deck's 0.3 s stroke is not quasi-static (kinetic/internal 1-3 "
                   "mid-stroke); a passing run needs about 3 s (see the deck's comment)")
def test_coarse_quasi_static(run):
    """Requirement: after the first quarter of the run, kinetic / internal energy of the blank stays below 5 % (the
    published quasi-static criterion, MODELS 6.4), recomputed from the history."""
    _, h, _ = run
    late = h["time"] >= 0.25 * h["time"][-1]
    ratio = h["kinetic_energy"][late] / np.maximum(h["internal_energy"][late], 1e-300)
    assert ratio.max() < 0.05
