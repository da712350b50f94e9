"""Requirement: the coarse square-tube forming decks (decks/forming/square_tube_{sm,ts}_coarse.yaml, MODELS 6.5)
run through the command line, pass their checks, and end in the shape the tools impose.

Each deck runs once (module fixture, `python -m fdeck.cli run`, one thread); the `ts` deck also with deformation
damping in place of its mass-proportional damping (nightly), which must meet every requirement here as well. The
references are independent of the run: the tool geometry as built by the generator (`square_tube(height=20.5)`,
the deck's variant files), the blank's half thickness and the exponential law's clearance, the energy ledger's own
definition recomputed from its history columns, and the fibre tension law (the yarns are nearly inextensible).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks" / "forming"
MODELS = ("sm", "ts")   # sm runs in the default tier (25 CPU-s), ts in the nightly one (47 CPU-s)

HALF = 0.115           # half thickness of the 0.23 mm blank [mm]
C0 = 0.05              # clearance of the decks' exponential law [mm]
TRAVEL = 20.0          # upper-tool travel of the coarse decks [mm] (the published 20)
HEIGHT, CLEAR, LIFT = 20.5, 0.3, 20.55   # block height, tool clearance, upper-tool lift of the variant files [mm]
Z_FLAT_END = -HEIGHT + CLEAR + LIFT - TRAVEL   # upper tool's outer flat at the end of the stroke: -19.65 mm


def square_tube_profiles(s):
    """Along the symmetry line y = 0 (plan signed distance s = x - 50 mm to the block's top edge): heights [mm] of
    the lower tool's surface offset up by the half thickness and of the upper tool's surface at the end of the
    stroke offset down by it (the corridor the blank's mid-surface must stay in), from the generator's profile."""
    from fdeck.physics.tools.generators import step_profile

    low = step_profile(s, HEIGHT, 80.0, 5.0, 5.0, HALF)
    up = step_profile(s, HEIGHT, 80.0, 5.0, 5.0, CLEAR - HALF) + LIFT - TRAVEL
    return low, up


def draw_in_of(s, z) -> float:
    """Draw-in [mm] of the end of a 140 mm inextensible yarn laid from x = 0 along the path z(s) (s = x - 50)."""
    length = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(s), np.diff(z)))])
    return 140.0 - (50.0 + float(np.interp(140.0, length, s)))


def taut_string(s, low, high):
    """Shortest path in the corridor low <= z <= high with fixed ends: the minimiser of sum (dz)^2 on a uniform
    grid under the bounds (in one dimension the two-obstacle Dirichlet problem's solution is the taut string)."""
    from scipy.optimize import minimize

    def f(z):
        d = np.diff(z)
        return float(d @ d), np.concatenate([[0.0], 2 * d]) - np.concatenate([2 * d, [0.0]])

    r = minimize(f, low.copy(), jac=True, bounds=list(zip(low, high)), method="L-BFGS-B",
                 options=dict(maxiter=20000, ftol=1e-15, gtol=1e-12))
    return r.x


def deformation_damped(model: str, folder: Path) -> Path:
    """The coarse deck of ``model`` with its mass-proportional damping replaced by deformation damping at 2 000 1/s
    (``steps[].deformation_damping``: no drag on the drawn-in flange), written into folder with the tools' files
    named absolutely; the same name as the shipped deck, so that its frames are named alike."""
    import yaml

    data = yaml.safe_load((DECKS / f"square_tube_{model}_coarse.yaml").read_text())
    step = data["steps"][0]
    assert step.pop("damping") == {"mass_proportional": 200.0}
    step["deformation_damping"] = {"rate": 2000.0}
    for tool in data["tools"].values():
        tool["surface"]["file"] = str(DECKS / tool["surface"]["file"])
    path = folder / f"square_tube_{model}_coarse.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


# ts_deformation: the ts deck without its drag (nightly, 40 CPU-s); sm without it ends at kinetic / internal 0.063
# on this fast coarse stroke (0.037 with the drag), so it is not a requirement (README, Forming)
@pytest.fixture(scope="module", params=["sm", pytest.param("ts", marks=pytest.mark.nightly),
                                        pytest.param("ts_deformation", marks=pytest.mark.nightly)])
def run(request, tmp_path_factory):
    """(history columns, final reference and current node positions, summary, exit code) of one coarse deck."""
    import meshio

    out = tmp_path_factory.mktemp(f"square_tube_{request.param}")
    model = request.param.split("_")[0]
    if request.param.endswith("_deformation"):
        deck = deformation_damped(model, tmp_path_factory.mktemp("deck"))
    else:
        deck = DECKS / f"square_tube_{model}_coarse.yaml"
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "run", str(deck), "-o", str(out)], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=600)
    names = open(out / "history.csv").readline().strip().split(",")
    data = np.loadtxt(out / "history.csv", delimiter=",", skiprows=1, ndmin=2)
    h = {n: data[:, i] for i, n in enumerate(names)}
    frames = sorted(p for p in out.glob(f"square_tube_{model}_coarse_0*.vtu"))
    m = meshio.read(frames[-1])
    X = m.points
    x = X + m.point_data["displacement"]
    summary = json.loads((out / "summary.json").read_text())
    return h, X, x, summary, r



def test_exit_zero_and_checks(run, request):
    """Requirement: each coarse deck completes with exit 0, i.e. its quasi-static (kinetic / internal <= 5 % after
    the first quarter) and energy-balance (<= 1 %) checks hold; both recomputed here from history.csv: the largest
    kinetic / internal ratio after a quarter of the run, and the largest |kinetic + internal + dissipated - work|
    (the ledger's balance column, MODELS 8) over the largest of the work and the internal energy. Without the mass
    damping (ts_deformation) the damping also dissipates under 10 % of the work the tools and the grips put in
    (measured 4.6 %; the shipped decks' mass damping, 200 1/s, takes about 40 % of it on the slow decks, README
    Forming), so the forming is not held up by the damping."""
    h, _, _, summary, r = run
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    t = h["time"]
    late = t >= 0.25 * t[-1]
    ratio = np.max(h["kinetic_energy"][late] / np.maximum(h["internal_energy"][late], 1e-30))
    assert ratio <= 0.05, ratio
    work = h["external_work"]
    err = np.max(np.abs(h["energy_balance_error"])) / max(np.max(np.abs(work)), np.max(h["internal_energy"]))
    assert err <= 0.01, err
    if request.node.callspec.params["run"].endswith("_deformation"):
        put_in = h["tool_work_upper"][-1] + h["tool_work_lower"][-1] + h["grip_work_grip"][-1] + work[-1]
        assert 0.0 < h["damping_energy"][-1] < 0.10 * put_in, (h["damping_energy"][-1], put_in)


def test_upper_force_zero_before_contact_and_pushing_after(run):
    """Requirement: the upper tool carries no force while its outer flat is farther from the blank than the
    exponential law's clearance (initial gap 0.35 - (0.175 + 0.115) = 0.06 mm > c0 = 0.05 mm: the first 0.01 mm of
    travel, which includes the 10 ms of pre-tension), and pushes the blank down once it has travelled 5 mm (the
    column `tool_upper_force_z` is negative then: it is the force the tool applies to the blank)."""
    h, *_ = run
    travel = -h["tool_upper_displacement_z"]
    fz = h["tool_upper_force_z"]
    before = travel < 0.005
    assert before.sum() > 3
    assert np.all(fz[before] == 0.0)
    after = travel > 5.0
    assert np.median(fz[after]) < 0.0, np.median(fz[after])


def test_flange_under_the_upper_flat(run):
    """Requirement: at the end of the stroke the flange in the middle of the sides (reference x > 80 mm and
    y < 40 mm, or the mirror: outside the block's foot and away from the corner wrinkles) lies in the channel
    between the upper tool's outer flat (z = -19.65 mm) and the lower tool's floor: its mid-surface between the
    lower tool's surface plus the half thickness and the upper flat minus it (the generator's profiles), each
    widened by the exponential law's clearance c0 (pressure starts there) and 0.01 mm of overclosure (the
    stiffness cap of 10 MPa/mm takes 0.1 MPa for it, far above the grips' and the flange's loads)."""
    _, X, x, _, _ = run
    flange = ((X[:, 0] > 80.0) & (X[:, 1] < 40.0)) | ((X[:, 1] > 80.0) & (X[:, 0] < 40.0))
    z = x[flange, 2]
    low, up = square_tube_profiles(np.array([40.0]))
    assert abs(up[0] - (Z_FLAT_END - HALF)) < 1e-9
    assert z.max() <= up[0] + C0 + 0.01, (z.max(), up[0])
    assert z.min() >= low[0] - C0 - 0.01, (z.min(), low[0])


def test_top_stays_on_the_block(run):
    """Requirement: the blank over the block top (reference x, y < 40 mm, inside the top-edge fillet that starts at
    45 mm) stays in the gap between the block top and the upper tool's plateau, which ends 0.85 mm above it: the
    mid-surface above the block top plus the half thickness, widened by the clearance c0 and 0.01 mm of overclosure
    (0.1 MPa at the capped stiffness), and below the plateau's surface itself (the mid-surface crossing a tool's
    surface would be a shell passing through it; the blank buckled over the top is squeezed in the 0.85 mm gap at
    the end of the stroke, so its upper face may overclose the plateau by more than c0)."""
    _, X, x, _, _ = run
    top = (X[:, 0] < 40.0) & (X[:, 1] < 40.0)
    z = x[top, 2]
    low, up = square_tube_profiles(np.array([-30.0]))
    assert z.min() >= low[0] - C0 - 0.01, (z.min(), low[0])
    assert z.max() < up[0] + HALF, (z.max(), up[0] + HALF)


def test_warp_line_keeps_its_length_and_draws_in(run):
    """Requirement: the warp yarn on the symmetry line y = 0 is nearly inextensible (tension law: 0.2 % strain at
    10 MPa, i.e. 2.3 N/mm, far above the grips' tens of newtons over the quarter): the polyline of its nodes keeps
    its 140 mm within 0.5 % (the chord of a 7.8 mm element across the 5 mm top fillet shortens it by at most
    0.3 %). Its end is drawn in as the corridor between the tools demands: at least the draw-in of the taut
    string through the corridor (the shortest admissible yarn) minus 2 mm (7.8 mm node spacing: one chord across
    each of the two bends, turning about 60 deg, saves at most 7.8 (1 - cos 30 deg) = 1.0 mm), and at most that of
    a yarn hugging the lower or the upper tool (the longest smooth paths in the corridor) plus 0.5 mm."""
    _, X, x, _, _ = run
    line = np.nonzero(np.abs(X[:, 1]) < 1e-6)[0]
    line = line[np.argsort(X[line, 0])]
    length = np.sum(np.linalg.norm(np.diff(x[line], axis=0), axis=1))
    assert abs(length / 140.0 - 1.0) <= 0.005, length
    draw_in = 140.0 - x[line[-1], 0]
    s = np.linspace(-50.0, 90.0, 1401)
    low, up = square_tube_profiles(s)
    flange = up[-1]
    hug_low = np.maximum(low, flange)
    hug_up = np.maximum(np.minimum(up, HALF), low)
    high = np.maximum(np.minimum(up, HALF), low)
    lo, hi = low.copy(), high.copy()
    lo[0] = hi[0] = HALF
    lo[-1] = hi[-1] = flange
    taut = draw_in_of(s, taut_string(s, lo, hi))
    longest = max(draw_in_of(s, hug_low), draw_in_of(s, hug_up))
    assert taut - 2.0 <= draw_in <= longest + 0.5, (draw_in, taut, longest)
