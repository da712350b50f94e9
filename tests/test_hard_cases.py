"""Hard cases of the fabric law stay numerically stable: in-plane shear driven into locking.

Each run must complete without NaN, keep its energy-balance error below 1 % of the largest energy, and keep the
invariants inside their admissible range (s < 1, c > I0_comp).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from helpers import DECKS, ROOT, deck_data, run_data

pytestmark = [pytest.mark.verification, pytest.mark.slow]


def balance_ratio(h) -> float:
    scale = max(np.abs(h[k]).max() for k in ("kinetic_energy", "internal_energy", "external_work"))
    return float(np.abs(h["energy_balance_error"]).max() / scale)


def test_bias_extension_pulled_past_the_pin_jointed_lock_stays_stable():
    """Requirement: a 3WEAVE bias sample pulled 10 % past the travel at which the pin-jointed net locks (shear angle
    90 deg at d = (sqrt 2 - 1)(H - W)) runs to completion, balanced, with s < 1 everywhere."""
    W, H = 50.0, 100.0
    d_lock = (math.sqrt(2) - 1) * (H - W)
    data = {
        "mesh": {"file": str(ROOT / "tests" / "data" / "bias_w50_n4.inp")},
        "materials": {"f": {"type": "fabric_hyper", "preset": "3weave"}},
        "sections": [{"elements": "ALL", "material": "f", "formulation": "fbar",
                      "orientation": {"warp_angle": 45}}],
        "boundary": [{"type": "fixed", "nodes": "GRIP_LOW"},
                     {"type": "fixed", "nodes": "GRIP_HIGH", "dofs": ["x", "z"]},
                     {"type": "displacement", "nodes": "GRIP_HIGH", "dofs": ["y"], "value": 1.1 * d_lock,
                      "amplitude": "smooth"}],
        "steps": [{"duration": 0.1}],
        "output": {"history_points": 100, "measures": [
            {"type": "element_average", "name": "max_shear", "elements": "ALL", "field": "shear_angle",
             "reduce": "max"}]},
    }
    problem, result, h = run_data(data)
    assert result.status == "completed", result.message
    assert all(np.isfinite(h[c]).all() for c in h)
    # 1 %: the issue's stability requirement
    assert balance_ratio(h) < 0.01
    # admissible range: |s| < 1 means a shear angle below 90 deg in every element, at every history row
    assert h["max_shear"].max() < 90.0
    # the sample did go far into the locking branch (s > I0 = 0.076 means > 4.4 deg; here well beyond 45 deg)
    assert h["max_shear"].max() > 45.0


def compaction_psi_prime(c: float) -> float:
    """[P] compaction form: dpsi/dc = K p / I0 ((1 - c/I0)^-(p+1) - 1) [MPa] (MODELS section 2)."""
    K, I0, p = 0.008, -1.675, 8.613
    return K * p / I0 * ((1.0 - c / I0) ** (-(p + 1.0)) - 1.0)


def test_confined_compaction_towards_the_singular_thickness_stays_stable_and_exact():
    """Requirement: 3WEAVE compacted in a rigid die (no lateral motion, the interior of a compaction test between
    sticking platens) to 75 % of the singular compaction I0_comp = -1.675 (thickness ratio 0.285, where the
    compaction tangent psi'' has grown 2e6-fold) runs to completion without NaN, balanced to 1 %, with c > I0_comp,
    and the platen pressure follows the closed form P33 = psi_c'(ln lambda) / lambda of uniaxial strain.
    Without lateral confinement the published law loses strong ellipticity near c = -1.1 (README, known limits)."""
    c_end = 0.75 * -1.675
    lam_end = math.exp(c_end)
    H = 2.54
    data = {
        "mesh": {"block": {"size": [10.0, 10.0, H], "divisions": [1, 1, 4]}},
        "materials": {"f": {"type": "fabric_hyper", "preset": "3weave"}},
        "sections": [{"elements": "all", "material": "f", "formulation": "fbar"}],
        "boundary": [{"type": "fixed", "nodes": "zmin"},
                     {"type": "fixed", "nodes": "all", "dofs": ["x", "y"]},
                     {"type": "displacement", "nodes": "zmax", "dofs": ["z"], "value": -(1 - lam_end) * H,
                      "amplitude": "smooth"}],
        "steps": [{"duration": 0.005}],
        "output": {"history_points": 200, "reactions": ["zmax"], "measures": [
            {"type": "element_average", "name": "c_min", "elements": "all", "field": "compaction_strain",
             "reduce": "min"},
            {"type": "node_displacement", "name": "top", "nodes": "zmax", "component": "z"}]},
    }
    problem, result, h = run_data(data)
    assert result.status == "completed", result.message
    assert all(np.isfinite(h[c]).all() for c in h)
    assert balance_ratio(h) < 0.01  # the issue's stability requirement
    assert h["c_min"].min() > -1.675  # admissible: never at or past the singular thickness
    assert h["c_min"][-1] == pytest.approx(c_end, rel=1e-3)  # and it did get there
    # Homogeneous uniaxial strain: nominal pressure from the closed form. 1 % (measured 0.55 %): the reaction also
    # carries the inertia of the column under the smooth ramp's acceleration.
    lam = 1.0 + h["top"] / H
    closed = np.array([compaction_psi_prime(math.log(v)) / v for v in lam])
    rows = lam < 0.9  # beyond the first 10 % the pressure exceeds 0.01 MPa and the relative check is meaningful
    assert np.allclose(-h["reaction_zmax_z"][rows] / 100.0, -closed[rows], rtol=0.01)
    # The step followed the tangent: at the end it is more than 100x below its rest value.
    assert h["dt"][-1] < h["dt"][1] / 100


@pytest.mark.long
@pytest.mark.parametrize("mass_factor", [pytest.param(1.0, marks=pytest.mark.nightly), pytest.param(10.0, marks=pytest.mark.nightly),
                                        pytest.param(40.0, marks=pytest.mark.nightly)])
def test_three_point_bending_1mm_fbar_with_fibre_bending_to_40mm_stays_stable(mass_factor):
    """Requirement: the 1 mm interlock three-point bending with F-bar + fibre bending runs to 40 mm of deflection
    without NaN, balanced to 1 % of the largest energy, with every element's in-plane and transverse shear below
    90 deg and its compaction above I0_comp; and the same with high mass scaling. The unscaled and the tenfold
    runs load 4x faster than decks/three_point_bending/fbar_bending_1mm.yaml (12.5 ms instead of 50 ms), the run
    with mass scaling 40 8x faster (6.25 ms, about 85 CPU-s); all three nightly (CI's 15 min); the deck itself runs
    at full length in studies/three_point_bending.py (README table)."""
    data = deck_data("three_point_bending/fbar_bending_1mm.yaml")
    # mass-scaled variant (the one in the default tier): loaded 8x faster than the deck, which only makes the hard
    # case harder (the assertions are stability, balance and bounds, not quasi-static answers)
    data["steps"][0]["duration"] = 0.0125 if mass_factor <= 10.0 else 0.00625
    if mass_factor != 1.0:
        data["steps"][0]["mass_scaling"] = {"factor": mass_factor}
    data["checks"] = {}
    data["output"]["measures"] += [
        {"type": "element_average", "name": "max_shear", "elements": "all", "field": "shear_angle", "reduce": "max"},
        {"type": "element_average", "name": "max_transverse_shear", "elements": "all",
         "field": "transverse_shear_warp", "reduce": "max"},
        {"type": "element_average", "name": "min_compaction", "elements": "all", "field": "compaction_strain",
         "reduce": "min"},
        {"type": "node_displacement", "name": "punch", "nodes": "load_line", "component": "z"}]
    problem, result, h = run_data(data, DECKS / "three_point_bending")
    assert result.status == "completed", result.message
    assert all(np.isfinite(h[c]).all() for c in h)
    assert balance_ratio(h) < 0.01  # the issue's stability requirement
    assert h["punch"][-1] == pytest.approx(-40.0, rel=1e-4)  # got to 40 mm (the last row is a cycle before the end)
    assert h["max_shear"].max() < 90.0 and h["max_transverse_shear"].max() < 90.0
    assert h["min_compaction"].min() > -0.6  # interlock preset I0_comp
    assert h["bending_energy"].max() > 0.0


@pytest.mark.parametrize("formulation", ["fbar", "full"])
@pytest.mark.parametrize("stretch, shear_deg, thickness", [(0.97, 10.0, 0.90), (0.93, 10.0, 0.85), (0.95, 5.0, 0.90)])
def test_compressed_sheared_fabric_hexahedra_have_no_discrete_instability(formulation, stretch, shear_deg, thickness):
    """Requirement (hard case: compressed fibres): a 6 x 6 x 2 patch of 3WEAVE hexahedra (5 mm x 5 mm x 1.27 mm,
    edges clamped) brought to a uniform state with the warp compressed (stretch 0.93-0.97), sheared by 5-10 deg and
    the thickness at 0.85-0.90 (the states of the tetrahedron's face bands, README Forming) has a positive definite
    stiffness: no element-scale mode (a row-by-row zig-zag, say) is unstable where the law itself is strongly
    elliptic there (the acoustic tensor's smallest eigenvalue over in-plane directions positive, checked too).
    Reference: positivity. Tangent by central differences of the nodal forces (h = 1e-6 mm); the smallest
    eigenvalues measured are 0.26-0.33 N/mm, far above the differences' round-off (~1e-6 N/mm); the bar 0.1 N/mm
    keeps a margin against a mode that merely approaches zero."""
    from scipy.linalg import eigh

    import test_fabric_hyper as fh_tests
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from helpers import central_stiffness

    data = {"mesh": {"block": {"size": [30.0, 30.0, 2.54], "divisions": [6, 6, 2]}},
            "materials": {"f": {"type": "3weave"}},
            "sections": [{"material": "f", "elements": "all", "formulation": formulation}],
            "steps": [{"duration": 0.01}]}
    p = compile_deck(Deck.model_validate(data))
    (g,) = p.groups
    F0 = fh_tests.compressed_sheared(stretch, math.radians(shear_deg))
    F0[2, 2] = thickness
    v = np.zeros_like(p.X)

    def force(x):
        f = np.zeros_like(x)
        g.update(x, v)
        g.add_forces(f)
        return f

    K = central_stiffness(force, p.X @ F0.T, 1e-6)
    X, top = p.X, p.X.max(axis=0)
    edge = np.isclose(X[:, 0], 0) | np.isclose(X[:, 0], top[0]) | np.isclose(X[:, 1], 0) | np.isclose(X[:, 1], top[1])
    free = np.repeat(~edge, 3)
    smallest = eigh(K[np.ix_(free, free)], eigvals_only=True)[0]

    A = fh_tests.tangent(F0, np.eye(3), fh_tests.params("3weave"), h=1e-6)
    N = np.array([[math.cos(t), math.sin(t), 0.0] for t in np.linspace(0.0, math.pi, 90, endpoint=False)])
    Q = np.einsum("iJkL,nJ,nL->nik", A, N, N)
    assert np.linalg.eigvalsh(0.5 * (Q + Q.transpose(0, 2, 1))).min() > 0.0  # the law is elliptic at F0
    assert smallest > 0.1, smallest
