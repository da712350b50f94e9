"""Bending without shear locking: the `ans` hexahedron (fdeck/physics/elements/hex8_ans.py) and its two volume-averaged
variants `ans_tbar` and `ans_fbar` (hex8_ans_fbar.py) against closed forms.

(a) static cantilevers against Timoshenko's beam over E_fibre / G = 1e-1..1e5, L/h = 5..200, symmetric and bimodular
fibres (``bending_helpers``); (b) the conformance suites of test_hex8.py run on them through their registry
parametrisation; (c) zero-energy modes of one distorted element; (e) the stable step against the exact critical
step; (d) the three-point-bending indicator against F-bar's (nightly, runs of the deck).
"""

from __future__ import annotations

import functools
from types import SimpleNamespace

import numpy as np
import pytest

from bending_helpers import Section, cantilever, fabric, make_group
from fdeck.compile.mesh import block

pytestmark = pytest.mark.verification

E = 100.0  # fibre (and compaction) modulus [MPa]; G = E / ratio
GRID_CI = [(eg, s, r) for r in (1.0, 0.01) for eg in (1e-1, 1e1, 1e3, 1e5) for s in (5, 20)]
GRID_NIGHTLY = [(eg, 200, r) for r in (1.0, 0.01) for eg in (1e-1, 1e1, 1e3, 1e5)]
ANS_FORMS = ("ans", "ans_tbar", "ans_fbar")
SHEAR_REFERENCE = {"ans": ("full",), "ans_tbar": ("full", "fbar"), "ans_fbar": ("fbar",)}
"""The elements without assumed shears (which do not lock where shear carries >= 60 % of the deflection) whose range
a formulation must stay in there: `full` for `ans`, `fbar` for `ans_fbar` (the same averaging); `ans_tbar` averages
part of what F-bar averages, the thickness stretch, so it sits at F-bar's answer where the section's warping needs
thickness changes and at the fully integrated one where F-bar's extra stiffness comes from the fibres (measured
/ Timoshenko, E/G = 1e5: L/h = 5 symmetric full 0.636, fbar 0.677, ans_tbar 0.677; L/h = 20 bimodular full 0.984,
fbar 0.934, ans_tbar 0.985)."""

ANS_FBAR_BIMODULAR = pytest.mark.xfail(strict=True, reason=(
    "measured 2026-11-26: `ans_fbar` is 12-18 % too stiff on bimodular fibres where bending carries >= 40 % of the "
    "deflection (0.821-0.879 of Timoshenko at L/h 5-20, 0.827-0.838 at 200). F-bar's averaging feeds a third of each "
    "point's volume change into every direction, so inside the compressed part of the section the element-scale "
    "variation of the soft (1 %) fibre compression meets the 100x stiffer weft and compaction moduli. It converges as "
    "the layers get thinner (E/G = 10, L/h = 20: 0.515 / 0.826 / 0.952 / 0.985 with 2 / 4 / 8 / 16 layers); "
    "`ans_tbar` averages the thickness stretch only and does not see it"))


def shear_share(eg, slender, ratio):
    """Share of the Timoshenko tip deflection that is shear [-] (h = 1, P = 1)."""
    sec = Section(E, ratio, E / eg, 1.0, 1.0)
    shear = slender * sec.shear_compliance()
    return shear / sec.timoshenko(1.0, float(slender))


def cantilever_cases(grid):
    """(form, E/G, L/h, compression ratio) over ``grid`` for every assumed-shear formulation; `ans_fbar`'s bimodular
    bending-dominated cases marked as the known failure ``ANS_FBAR_BIMODULAR``."""
    for form in ANS_FORMS:
        for eg, s, r in grid:
            known = form == "ans_fbar" and r < 1.0 and shear_share(eg, s, r) < 0.6
            yield pytest.param(form, eg, s, r, marks=ANS_FBAR_BIMODULAR if known else (), id=f"{form}-{eg:g}-{s}-{r:g}")


def check_cantilever(form, eg, slender, ratio):
    w, ref = cantilever(form, E, E / eg, ratio, slender)
    share = shear_share(eg, slender, ratio)
    if share < 0.6:
        # 3 %: the requirement. Discretisation alone stays inside it: constant curvature per element gives
        # the -1/(4 n^2) of linear Timoshenko elements (n >= 5 elements: <= 1 %); bimodular, the neutral axis inside
        # the top layer, integrated by two points, +2.7 % measured; the volume averaging of `ans_fbar` integrates the
        # volumetric third of the bending stiffness piecewise-constant over each of the n = 4 layers, +1/(3 n^2)
        # = +2.1 % (measured +2.12 % at L/h = 200). A locked element is off by 10-1000x (F-bar: 0.024 at
        # E/G = 0.1, 0.0008 bimodular)
        assert w == pytest.approx(ref, rel=0.03), (form, eg, slender, ratio, w / ref)
    else:
        # shear-dominated: the deflection is set by the section's warping, which four layers of constant shear
        # represent coarsely, for every formulation alike (it is not locking). The element must then stay within
        # 1 % of the range of its counterparts without assumed shears (``SHEAR_REFERENCE``; measured: ans / full
        # and ans_fbar / fbar within 0.1 %, ans_tbar at most 0.05 % outside full..fbar) and be neither softer than
        # Timoshenko nor stiffer than the unwarped section can make it
        w_ref = [cantilever(other, E, E / eg, ratio, slender)[0] for other in SHEAR_REFERENCE[form]]
        assert 0.99 * min(w_ref) <= w <= 1.01 * max(w_ref), (form, eg, slender, ratio, w, w_ref)
        assert 0.5 * ref < w <= 1.03 * ref, (form, eg, slender, ratio, w / ref)
    return w / ref


@pytest.mark.parametrize("form,eg,slender,ratio", list(cantilever_cases(GRID_CI)))
def test_cantilever_tip_deflection_matches_timoshenko(form, eg, slender, ratio):
    """Requirement: a cantilever of `ans` (`ans_tbar`, `ans_fbar`) hexahedra (four through the thickness, elements
    2 h long, at least five along) deflects within 3 % of Timoshenko's closed form (bimodular: shifted neutral axis,
    energy-consistent shear coefficient) for E_fibre / G from 1e-1 to 1e5, symmetric and bimodular (1 %) fibres: no
    shear locking. Measured / Timoshenko where bending carries >= 40 % of the deflection: ans 0.986-0.998
    symmetric and 1.008-1.025 bimodular; ans_tbar the same to 4 digits; ans_fbar 1.005-1.019 symmetric, bimodular
    0.821-0.879 (known failure, ``ANS_FBAR_BIMODULAR``). In the shear-dominated cases (share >= 0.6) 0.64-0.985,
    in the range of the elements without assumed shears (see ``check_cantilever``)."""
    check_cantilever(form, eg, slender, ratio)


@pytest.mark.nightly
@pytest.mark.parametrize("form,eg,slender,ratio", list(cantilever_cases(GRID_NIGHTLY)))
def test_slender_cantilever_tip_deflection_matches_timoshenko(form, eg, slender, ratio):
    """Requirement: as the CI grid, at L/h = 200 (100 elements along; 3-12 s each). Measured: ans and ans_tbar
    symmetric 0.979-1.000, bimodular 1.027-1.028 (the two-point integration of the layer holding the neutral axis);
    ans_fbar symmetric 0.991-1.021, bimodular 0.827-0.838 (known failure)."""
    check_cantilever(form, eg, slender, ratio)


def test_fbar_locks_where_ans_does_not():
    """Requirement: the reason for the formulation is visible: at E/G = 0.1 (stiff transverse shear) F-bar locks
    (tip deflection below half of Timoshenko's; measured 0.024) while `ans` is within 3 % (measured 0.997)."""
    w_fbar, ref = cantilever("fbar", E, E / 0.1, 1.0, 20)
    w_ans, _ = cantilever("ans", E, E / 0.1, 1.0, 20)
    assert w_fbar < 0.5 * ref
    assert w_ans == pytest.approx(ref, rel=0.03)


def element_stiffness(form, X, conn, kind, p, h=1e-6):
    """24 x 24 tangent stiffness of one element at rest by central differences of its forces [N/mm]."""
    g = make_group(form, X, conn, kind, p)
    K = np.zeros((24, 24))
    for k in range(24):
        a, i = divmod(k, 3)
        cols = []
        for s in (1.0, -1.0):
            x = X.copy()
            x[conn[0, a], i] += s * h  # column k is local node a, as the rows of fe
            g.update(x, np.zeros_like(x))
            cols.append(g.fe.reshape(24).copy())
        K[:, k] = (cols[0] - cols[1]) / (2 * h)
    return 0.5 * (K + K.T)


@pytest.mark.parametrize("form", ANS_FORMS)
@pytest.mark.parametrize("material", ["neo_hookean", "fabric E/G=10", "fabric E/G=1e3", "fabric E/G=1e3 bimodular"])
def test_no_zero_energy_mode_beyond_rigid_motions(material, form):
    """Requirement: one distorted `ans` (`ans_tbar`, `ans_fbar`) element has exactly six zero eigenvalues (the rigid
    motions) in its stiffness at rest, and its seventh is at least half the fully integrated element's (which has no
    spurious mode): the assumed shears soften bending modes, they must not create a mechanism. Zero means below 1e-9
    of the largest. Central differences with a step of 1e-7 mm: round-off ~1e-16, and the bimodular kink at zero
    strain gives an error proportional to the step, 2.4e-11 (`ans`), 5.6e-10 (`ans_tbar`) and 5.4e-10 (`ans_fbar`,
    and `fbar` alike: the averaging puts every point on the kink; ten times more with a step of 1e-6 mm). The
    softest genuine mode sits near G/E of the largest (1.5e-5 at E/G = 1e3), hence a comparison with `full` rather
    than a fixed floor (measured / full: ans 0.72-1.02, ans_tbar 0.65-1.02, ans_fbar 0.63-1.02)."""
    from fdeck.registry import CARDS, MATERIALS

    m = block((0, 0, 0), (2.0, 1.5, 0.5), (1, 1, 1))
    rng = np.random.default_rng(7)
    X = m.X + 0.15 * rng.uniform(-1, 1, m.X.shape) * np.array([2.0, 1.5, 0.5])
    conn = m.cells["hexahedron"]
    if material == "neo_hookean":
        kind = MATERIALS["neo_hookean"]
        p = kind.pack(CARDS["material"]["neo_hookean"].card(type="neo_hookean", density=1e-9, youngs_modulus=1e3,
                                                             poisson_ratio=0.3))
    else:
        eg = 10.0 if "10" in material else 1e3
        kind, p = fabric(E, E / eg, 0.01 if "bimodular" in material else 1.0)
    lam = np.linalg.eigvalsh(element_stiffness(form, X, conn, kind, p, h=1e-7))
    lam_full = np.linalg.eigvalsh(element_stiffness("full", X, conn, kind, p, h=1e-7))
    lam_max = lam.max()
    assert np.all(np.abs(lam[:6]) < 1e-9 * lam_max), lam[:7] / lam_max
    assert lam[6] > 0.5 * lam_full[6], (lam[6], lam_full[6])


@pytest.mark.parametrize("form", ANS_FORMS)
@pytest.mark.parametrize("mat", ["3weave", "interlock"])
@pytest.mark.parametrize("shape_name,state", [("THIN", "rest"), ("THIN", "warp 1%"), ("THIN", "trellis 30 deg"),
                                              ("SKEWED", "rest"), ("SKEWED", "warp 1%")])
def test_stable_step_is_below_the_exact_critical_step(mat, shape_name, state, form):
    """Requirement: the step of an `ans` (`ans_tbar`, `ans_fbar`) fabric section never exceeds the exact critical
    step of a small mesh (largest eigenvalue of M^-1 K, K by central differences): exact / estimate >= 1 (the engine
    then keeps its 10 % dt_safety margin). The assumed shears only remove stiffness from the fully integrated
    element, whose directional rule the formulation keeps; the averaged variants add F-bar's coupling 1/9
    (``test_averaged_variants_need_the_coupling_term``). Measured: ans 1.02-3.53, ans_tbar 1.10-2.74, ans_fbar
    1.10-2.76."""
    ratio = critical_step_ratio(form, mat, shape_name, state)
    assert ratio >= 1.0, ratio


def critical_step_ratio(form, mat, shape_name, state, coupling=None):
    """Exact critical step / the group's estimate on ``test_stable_step``'s small meshes; ``coupling`` replaces
    the group's ``dt_coupling`` when given."""
    import test_stable_step as ts
    from fdeck.registry import CARDS as REGISTERED, MATERIALS

    size, divisions = getattr(ts, shape_name)
    angle, distort = (30.0, 0.15) if shape_name == "SKEWED" else (0.0, 0.0)
    mesh = block((0, 0, 0), size, divisions)
    X = mesh.X + distort * np.random.default_rng(0).uniform(-1, 1, mesh.X.shape) * np.divide(size, divisions)
    card = REGISTERED["material"]["fabric_hyper"].card(**ts.CARDS[mat])
    kind = MATERIALS["fabric_hyper"]
    p, conn = kind.pack(card), mesh.cells["hexahedron"]
    n = len(conn)
    a = np.radians(angle)
    frame = np.array([[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0], [0, 0, 1.0]])
    from fdeck.registry import FORMULATIONS

    section = SimpleNamespace(formulation=form, hourglass=None)
    orientation = SimpleNamespace(frames=lambda: np.broadcast_to(frame, (n, 3, 3)).copy())
    g = FORMULATIONS[form].build("g", section, X, conn, np.arange(1, n + 1), kind, np.broadcast_to(p, (n, len(p))),
                                 orientation, np.full(n, card.density), "hexahedron")
    if coupling is not None:
        g.dt_coupling = coupling
    x = ts.deformed(X, state)
    return ts.exact_critical_dt(X, g, x) / g.stable_dt()


@pytest.mark.parametrize("form", ["ans_tbar", "ans_fbar"])
def test_averaged_variants_need_the_coupling_term(form):
    """Requirement: the coupling 1/9 in the step of `ans_tbar` and `ans_fbar` is needed: without it the estimate of a
    thin interlock mesh at rest exceeds the exact critical step (measured exact / estimate 0.71 for both, 2.53-2.54
    with it), because the averaging passes a third of a thickness (volume) change into the stiff fibre stretch."""
    assert critical_step_ratio(form, "interlock", "THIN", "rest") >= 1.0
    assert critical_step_ratio(form, "interlock", "THIN", "rest", coupling=0.0) < 1.0


@functools.lru_cache(maxsize=None)
def indicator(deck: str, form: str) -> float:
    """Final spurious-mode indicator [mm] of a three-point-bending deck run with formulation ``form``; cached, so
    F-bar's run is made once for all the formulations compared with it."""
    from helpers import DECKS, deck_data, run_data

    data = deck_data(f"three_point_bending/{deck}")
    data["sections"][0]["formulation"] = form
    problem, result, h = run_data(data, DECKS / "three_point_bending")
    return float(h["spurious_mode_indicator"][-1])


ANS_INDICATOR = pytest.mark.xfail(strict=True, reason=(
    "measured 2026-11-25 (again 2026-11-26: 1.989 / 0.0835 against 0.118 / 0.0219 mm) on the 3 mm deck: ans alone "
    "1.99 mm against F-bar's 0.118, ans + fibre bending 0.084 mm against F-bar + fibre bending 0.022 mm: the assumed "
    "shears remove the parasitic shear stiffness that also held back [B]'s spurious transverse modes"))


@pytest.mark.nightly
@pytest.mark.parametrize("deck,form", [
    pytest.param("fbar_bending_3mm.yaml", "ans", marks=ANS_INDICATOR),
    ("fbar_bending_3mm.yaml", "ans_tbar"),
    ("fbar_bending_3mm.yaml", "ans_fbar"),
    pytest.param("fbar_3mm.yaml", "ans", marks=ANS_INDICATOR),
    ("fbar_3mm.yaml", "ans_tbar"),
    ("fbar_3mm.yaml", "ans_fbar"),
])
def test_three_point_bending_indicator_no_worse_than_fbar(deck, form):
    """Requirement (issue 9 (d)): on the 3 mm three-point-bending deck with fibre bending (and, as a harder check,
    without it), swapping F-bar for the assumed-shear formulation does not raise the spurious-mode indicator above
    F-bar's (both runs made here, about 1 min each unloaded; 5 % margin for the run-to-run difference of two explicit
    runs, which is a step-size effect).

    Measured 2026-11-26 (one thread, loaded machine), final indicator [mm] / cycles / punch force at 40 mm [N]:
    with fibre bending: fbar 0.02186 / 71 994 / 958, ans_tbar 0.02189 / 71 851 / 885 (1.001 x F-bar),
    ans_fbar 0.02212 / 71 833 / 897 (1.012 x), ans 0.0835 / 65 599 / 604; without: fbar 0.1179 / 71 536 / 770,
    ans_tbar 0.1058 / 71 475 / 691, ans_fbar 0.1069 / 71 470 / 710, ans 1.989 / 65 209 / 196. The averaged
    variants keep F-bar's coupling of element-scale thickness (volume) changes into the fibre stretch, which is what
    holds back the modes (module docstring of hex8_ans_fbar). These figures predate the mean-free shear modification
    (hex8_ans); with it the four asserted cases pass again (nightly run 2026-11-26, figures not re-recorded).
    After `ans_tbar`'s true-thickness update (2026-11-29): ans_tbar 0.02178 with fibre bending (0.997 x F-bar's
    0.02186), 0.1140 without (0.967 x 0.1179). Not tested here (30 min per run): on the 1 mm deck
    with fibre bending fbar 0.01751, ans_fbar 0.01836 (1.049x), ans_tbar 0.02106 (1.20x, README)."""
    ours, fbar = indicator(deck, form), indicator(deck, "fbar")
    assert ours <= 1.05 * fbar, (form, ours, fbar)
