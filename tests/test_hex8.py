"""Conformance of the hexahedron formulations: patch test, rigid motion, objectivity, forces = -dW/dx."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.compile.mesh import block
from fdeck.physics.elements.hex8 import Hex8Group
from fdeck.registry import CARDS, FORMULATIONS, MATERIALS

from helpers import central_gradient, stored_energy, term

pytestmark = pytest.mark.conformance
FORMS = sorted(k for k, v in CARDS["formulation"].items() if "hexahedron" in v.cell_types)  # shells: test_shell4
MATS = ["linear_elastic", "neo_hookean"]


def make_group(form, mat="neo_hookean", X=None, conn=None, nu=0.3):
    """The group the registry builds for formulation ``form`` (its own class: `ans` is not a ``Hex8Group`` mode;
    constructing ``Hex8Group`` with its name would silently run full integration)."""
    kind = MATERIALS[mat]
    card = CARDS["material"][mat].card(type=mat, density=1e-9, youngs_modulus=1000.0, poisson_ratio=nu)
    p = kind.pack(card)
    n = len(conn)
    section = SimpleNamespace(formulation=form, hourglass=SimpleNamespace(type="stiffness", coefficient=0.1))
    orientation = SimpleNamespace(frames=lambda: np.broadcast_to(np.eye(3), (n, 3, 3)).copy())
    return FORMULATIONS[form].build("g", section, X, conn, np.arange(1, n + 1), kind, np.broadcast_to(p, (n, len(p))),
                                    orientation, np.full(n, 1e-9), "hexahedron")


def test_make_group_builds_each_formulation_s_own_group():
    """Requirement: the suites below test each formulation's own element, not ``Hex8Group`` under another name:
    on a random non-affine motion `ans` forces differ from `full`'s by more than 5 % of the largest force (measured
    20 %, the removed parasitic shear; the same class would give exactly 0)."""
    X, conn = distorted_patch()
    x = X + 0.05 * np.random.default_rng(0).normal(size=X.shape)
    f_full = internal_forces(make_group("full", X=X, conn=conn), x)
    f_ans = internal_forces(make_group("ans", X=X, conn=conn), x)
    assert type(make_group("ans", X=X, conn=conn)) is not Hex8Group
    assert np.abs(f_ans - f_full).max() > 0.05 * np.abs(f_full).max()


def distorted_patch(seed=0):
    """2x2x2 block with every interior and boundary node moved randomly (but not inverted)."""
    m = block((0, 0, 0), (2.0, 1.5, 1.0), (2, 2, 2))
    rng = np.random.default_rng(seed)
    X = m.X + 0.12 * rng.uniform(-1, 1, m.X.shape) * np.array([1.0, 0.75, 0.5])
    return X, m.cells["hexahedron"]


def internal_forces(g, x, v=None):
    v = np.zeros_like(x) if v is None else v
    g.update(x, v)
    f = np.zeros_like(x)
    g.add_forces(f)
    return f


def parallelepiped_patch():
    """2x2x2 block under an affine map (sheared and stretched): every element a parallelepiped."""
    m = block((0, 0, 0), (2.0, 1.5, 1.0), (2, 2, 2))
    B = np.array([[1.0, 0.3, 0.1], [0.0, 1.0, 0.2], [0.1, 0.0, 0.8]])
    return m.X @ B.T, m.cells["hexahedron"]


def patch_cases():
    for mesh in ("distorted", "parallelepiped"):
        for mat in MATS:
            for form in FORMS:
                yield pytest.param(form, mat, mesh, id=f"{mesh}-{mat}-{form}")


@pytest.mark.parametrize("form,mat,mesh", list(patch_cases()))
def test_patch_test_linear_field_gives_exact_constant_stress(form, mat, mesh):
    """Requirement: on a distorted mesh (and on one of parallelepipeds) a homogeneous deformation x = A X gives the
    exact stress in every element (1e-8 relative) and zero force on the interior node (equilibrium)."""
    X, conn = distorted_patch() if mesh == "distorted" else parallelepiped_patch()
    g = make_group(form, mat, X, conn)
    A = np.array([[1.02, 0.01, -0.005], [0.004, 0.99, 0.008], [0.0, 0.006, 1.015]])
    x = X @ A.T + np.array([1.0, -2.0, 0.5])
    f = internal_forces(g, x)
    P_exact = np.zeros((3, 3))
    MATERIALS[mat].point(A, np.eye(3), g.params[0], np.zeros(0), P_exact)
    # F at every point equals A; stress equals the material's at A (Fbar = F for a homogeneous field)
    assert np.abs(g.F - A).max() < 1e-12
    assert np.abs(g.P - P_exact).max() < 1e-8 * np.abs(P_exact).max()
    interior = np.argmin(np.linalg.norm(X - X.mean(axis=0), axis=1))
    scale = np.abs(f).max()
    # round-off level: sums of ~64 terms of size `scale`
    assert np.abs(f[interior]).max() < 1e-10 * scale


@pytest.mark.parametrize("form", FORMS)
def test_rigid_motion_gives_no_force_and_no_energy(form):
    """Requirement: a large rigid rotation (90 deg about a skew axis) plus a translation gives zero force."""
    X, conn = distorted_patch(1)
    g = make_group(form, "neo_hookean", X, conn)
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    K = np.cross(np.eye(3), axis)
    R = np.eye(3) + K + K @ K  # Rodrigues with sin = 1, 1 - cos = 1 (90 deg)
    f = internal_forces(g, X @ R.T + 5.0)
    assert np.abs(f).max() < 1e-9  # forces of order 1e3 N would appear for a 1 % strain; round-off only
    assert abs(term(g, "strain_energy")) < 1e-12 and stored_energy(g) < 1e-12


@pytest.mark.parametrize("form", FORMS)
def test_objectivity_stress_rotates_with_the_body(form):
    """Requirement: superposing a rigid rotation Q on a deformation rotates the Cauchy stress as Q s Q^T and the
    nodal forces as Q f, energies unchanged."""
    X, conn = distorted_patch(2)
    g = make_group(form, "neo_hookean", X, conn)
    rng = np.random.default_rng(3)
    x = X + 0.05 * rng.normal(size=X.shape)
    f1 = internal_forces(g, x)
    e1 = stored_energy(g)
    s1 = g.cell_fields()["stress"]
    Q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    Q *= np.sign(np.linalg.det(Q))
    f2 = internal_forces(g, x @ Q.T)
    e2 = stored_energy(g)
    s2 = g.cell_fields()["stress"]
    assert np.abs(f2 - f1 @ Q.T).max() < 1e-9 * np.abs(f1).max()
    assert e2 == pytest.approx(e1, rel=1e-11)

    def full(s):
        return np.array([[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]])
    for a, b in zip(s1, s2):
        assert np.abs(Q @ full(a) @ Q.T - full(b)).max() < 1e-9 * np.abs(a).max()


@pytest.mark.parametrize("form", FORMS)
def test_forces_are_minus_energy_gradient(form):
    """Requirement: internal forces equal dW/dx (W = strain + hourglass energy) by central differences."""
    X, conn = distorted_patch(4)
    g = make_group(form, "neo_hookean", X, conn, nu=0.45)
    rng = np.random.default_rng(5)
    x = X + 0.08 * rng.normal(size=X.shape)
    f = internal_forces(g, x)

    def energy(y):
        internal_forces(g, y)
        return stored_energy(g)
    fd = central_gradient(energy, x, h=1e-6)
    # central differences with h = 1e-6 mm on energies ~1e1 mJ: truncation ~h^2, round-off ~1e-16/h -> 1e-7
    assert np.abs(f - fd).max() < 1e-6 * np.abs(fd).max()


@pytest.mark.parametrize("form", FORMS)
def test_forces_are_minus_energy_gradient_fabric_on_a_tilted_frame(form):
    """Requirement: as above with the `interlock` fabric on a random fibre frame (the laws and `ans_tbar`'s thickness
    stretch read the frame), every mode loaded by a random 3 % motion: FD agreement 1e-6 relative (measured
    7e-11 to 2.3e-10)."""
    kind = MATERIALS["fabric_hyper"]
    p = kind.pack(CARDS["material"]["fabric_hyper"].card(type="fabric_hyper", preset="interlock"))
    X, conn = distorted_patch(4)
    n = len(conn)
    Q = np.linalg.qr(np.random.default_rng(1).normal(size=(3, 3)))[0]
    Q *= np.sign(np.linalg.det(Q))
    section = SimpleNamespace(formulation=form, hourglass=SimpleNamespace(type="stiffness", coefficient=0.1))
    orientation = SimpleNamespace(frames=lambda: np.broadcast_to(Q, (n, 3, 3)).copy())
    g = FORMULATIONS[form].build("g", section, X, conn, np.arange(1, n + 1), kind, np.broadcast_to(p, (n, len(p))),
                                 orientation, np.full(n, 1e-9), "hexahedron")
    x = X + 0.03 * np.random.default_rng(5).normal(size=X.shape)
    f = internal_forces(g, x)

    def energy(y):
        internal_forces(g, y)
        return stored_energy(g)
    fd = central_gradient(energy, x, h=1e-6)
    assert np.abs(f - fd).max() < 1e-6 * np.abs(fd).max()


@pytest.mark.parametrize("form,locks", [("full", True), ("fbar", False), ("ans", True), ("ans_tbar", True),
                                        ("ans_fbar", False)])
def test_fbar_cures_volumetric_locking_full_integration_locks(form, locks):
    """Requirement: for nu -> 0.5 the fully integrated hexahedron locks in bending-like modes and F-bar does not:
    the energy of a bending-like (hourglass x-displacement) mode stays bounded with F-bar. So does `ans_fbar`'s
    (mean dilatation); `ans` and `ans_tbar` (which averages the thickness stretch, not the volume) lock like `full`
    (measured ratios: full 963, ans and ans_tbar 1240, fbar and ans_fbar 0.87)."""
    X, conn = block((0, 0, 0), (1.0, 1.0, 1.0), (1, 1, 1)).X, block((0, 0, 0), (1, 1, 1), (1, 1, 1)).cells["hexahedron"]
    from fdeck.physics.elements.hex8 import HOURGLASS_BASE

    mode = np.zeros_like(X)
    mode[conn[0], 0] = 1e-4 * HOURGLASS_BASE[2]  # x-displacement varying like zeta*xi: bending about y
    energies = {}
    for nu in (0.3, 0.4999):
        g = make_group(form, "linear_elastic", X, conn, nu=nu)
        internal_forces(g, X + mode)
        energies[nu] = term(g, "strain_energy")
    if locks:  # energy grows with the bulk modulus (locking), by more than 100x from nu=0.3 to 0.4999
        assert energies[0.4999] / energies[0.3] > 100
    else:  # the mode is isochoric in the mean, so the bulk modulus barely enters (less than 2x)
        assert energies[0.4999] / energies[0.3] < 2
