"""Conformance of the 4-node shell (sm, ts, membrane; quadrilaterals and degenerate-quad triangles): patch tests,
rigid motion, objectivity, forces and director forces = derivatives of the energy, stress-free curved reference,
lumped masses and inertias.

Meshes are 3 x 3 patches (9 quads or 18 triangles): the smallest with interior nodes surrounded by distorted
elements, which is what the patch tests need; the derivative checks cost 2 x 6 x 16 energy evaluations each.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from shell_helpers import one_thread  # noqa: F401  (fixture)
from shell_helpers import SECTIONS, evaluate, linear_fabric, make, patch, rotation

pytestmark = [pytest.mark.conformance, pytest.mark.usefixtures("one_thread")]
ALL = sorted(SECTIONS)
MESHES = [False, True]  # quadrilaterals, triangles


def interior(X):
    return np.nonzero((X[:, 0] > 0.5) & (X[:, 0] < 2.5) & (X[:, 1] > 0.3) & (X[:, 1] < 1.7))[0]


@pytest.mark.parametrize("triangles", MESHES, ids=["quad", "tri"])
@pytest.mark.parametrize("section", ALL)
def test_membrane_patch_test(section, triangles):
    """Requirement: a homogeneous in-plane deformation x = A X of a distorted flat patch gives F = A at every point
    and level (1e-12), the law's stress there, and zero force and moment on the interior nodes (1e-10 of the
    largest nodal force: sums of a few terms of that size)."""
    X, conn, ctype = patch(triangles)
    g, st = make(section, X, conn, ctype)
    A = np.array([[1.03, 0.02, 0.0], [-0.01, 0.98, 0.0], [0.0, 0.0, 1.0]])
    x = X @ A.T + np.array([0.5, -1.0, 2.0])
    f, gd, m, W = evaluate(g, st, x)
    assert np.abs(g.F - A).max() < 1e-12
    from fdeck.physics.materials.fabric_membrane import point
    P = np.zeros((3, 3))
    point(A, g.frame[0], g.params[0], np.zeros(0), P)
    assert np.abs(g.P[0, 0, 0] - P).max() < 1e-10 * np.abs(P).max()
    inner = interior(X)
    assert len(inner) == 4
    scale = np.abs(f).max()
    assert scale > 0 and np.abs(f[inner]).max() < 1e-10 * scale
    assert np.abs(m).max() < 1e-10 * scale * 3.0  # no bending anywhere (moments in N mm, lever ~3 mm)


@pytest.mark.parametrize("triangles", MESHES, ids=["quad", "tri"])
@pytest.mark.parametrize("section", ["sm", "ts", "ts_lobatto"])
def test_bending_patch_test(section, triangles):
    """Requirement: a constant-curvature (Kirchhoff) state w = (kx X^2 + ky Y^2 + 2 kxy X Y) / 2 with directors
    normal to it, prescribed at every node of a distorted flat patch, leaves the interior nodes in equilibrium
    (force and moment below 1e-3 of the largest), sm's bending energy equals 1/2 int k:D:k over the patch (1e-6)
    and the MITC shear energy is below 1e-10 of it (zero shear in pure bending).
    The state is exact for the linear theory; what is left is the membrane stretch (grad w)^2 / 2 it implies,
    whose forces over the bending ones are E h k L^3 / D (sm) and k L^2 / h (ts): below 1e-4 with the soft
    membrane (E = 100 MPa) and k = 1e-7 /mm used here, and above round-off (1e-7)."""
    X, conn, ctype = patch(triangles, seed=1)
    g, st = make(section, X, conn, ctype, mat=linear_fabric(100.0))
    kx, ky, kxy = 1e-7, -0.6e-7, 0.3e-7
    X0, Y0 = X[:, 0], X[:, 1]
    w = 0.5 * (kx * X0**2 + ky * Y0**2 + 2 * kxy * X0 * Y0)
    x = X + np.outer(w, [0, 0, 1.0])
    d = np.column_stack([-(kx * X0 + kxy * Y0), -(kxy * X0 + ky * Y0), np.ones(len(X))])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    f, gd, m, W = evaluate(g, st, x, d)
    inner = interior(X)
    # pure bending loads the boundary with moments only: forces are compared with (largest moment) / (1 mm edge)
    scale = np.abs(m).max()
    assert scale > 0
    assert np.abs(f[inner]).max() < 1e-3 * scale and np.abs(m[inner]).max() < 1e-3 * scale
    if section == "sm":
        EI, GI = SECTIONS["sm"]["bending_stiffness"], SECTIONS["sm"]["twisting_stiffness"]
        area = g.area.sum()
        exact = 0.5 * area * (EI * kx**2 + EI * ky**2 + 4 * GI * kxy**2)
        assert g.e_b.sum() == pytest.approx(exact, rel=1e-6)
        assert g.e_s.sum() < 1e-10 * exact
    assert g.e_s.sum() < 1e-10 * W


@pytest.mark.parametrize("triangles", MESHES, ids=["quad", "tri"])
@pytest.mark.parametrize("section", ALL)
def test_rigid_motion_gives_no_force_moment_or_energy(section, triangles):
    """Requirement: a 90 deg rotation about a skew axis plus a translation of positions and directors of a curved,
    distorted patch gives zero force, director force and energy (round-off: forces of a 1 % strain would be
    ~1 N here)."""
    X, conn, ctype = patch(triangles, seed=2, curved=0.3)
    g, st = make(section, X, conn, ctype)
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    K = np.cross(np.eye(3), axis)
    R = np.eye(3) + K + K @ K  # 90 deg
    f, gd, m, W = evaluate(g, st, X @ R.T + 5.0, st.d0 @ R.T)
    assert np.abs(f).max() < 1e-11 and np.abs(gd).max() < 1e-11 and abs(W) < 1e-20


@pytest.mark.parametrize("section", ALL)
def test_objectivity_forces_rotate_with_the_body(section):
    """Requirement: superposing a rigid rotation Q on a deformed state (x, d) rotates forces, director forces and
    moments by Q and leaves the energy unchanged (1e-10 relative)."""
    X, conn, ctype = patch(False, seed=3, curved=0.2)
    g, st = make(section, X, conn, ctype)
    rng = np.random.default_rng(4)
    x = X + 0.03 * rng.normal(size=X.shape)
    d = st.d0 + (0.1 * rng.normal(size=X.shape) if g.has_dir else 0.0)
    d /= np.where(np.linalg.norm(d, axis=1) > 0, np.linalg.norm(d, axis=1), 1.0)[:, None]
    f1, g1, m1, W1 = evaluate(g, st, x, d)
    Q = rotation(rng)
    f2, g2, m2, W2 = evaluate(g, st, x @ Q.T, d @ Q.T)
    assert W2 == pytest.approx(W1, rel=1e-10)
    assert np.abs(f2 - f1 @ Q.T).max() < 1e-10 * np.abs(f1).max()
    if g.has_dir:
        assert np.abs(g2 - g1 @ Q.T).max() < 1e-10 * np.abs(g1).max()
        assert np.abs(m2 - m1 @ Q.T).max() < 1e-10 * np.abs(m1).max()


@pytest.mark.parametrize("triangles", MESHES, ids=["quad", "tri"])
@pytest.mark.parametrize("section", ALL)
def test_forces_and_director_forces_are_energy_derivatives(section, triangles):
    """Requirement: on a curved, distorted patch in a random large deformation (strains ~5 %, directors turned
    ~6 deg), the nodal forces equal dW/dx and the director forces dW/dd by central differences (1e-6 relative),
    and the moments are d x (dW/dd). This is what makes the energy ledger close."""
    X, conn, ctype = patch(triangles, seed=5, curved=0.3)
    g, st = make(section, X, conn, ctype)
    rng = np.random.default_rng(6)
    x = X + 0.05 * rng.normal(size=X.shape)
    d = st.d0.copy()
    if g.has_dir:
        d = d + 0.1 * rng.normal(size=X.shape)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
    f, gd, m, W = evaluate(g, st, x, d)
    h = 1e-6
    fd, gfd = np.zeros_like(x), np.zeros_like(x)
    for n in range(len(x)):
        for i in range(3):
            e = np.zeros_like(x)
            e[n, i] = h
            fd[n, i] = (evaluate(g, st, x + e, d)[3] - evaluate(g, st, x - e, d)[3]) / (2 * h)
            if g.has_dir:
                gfd[n, i] = (evaluate(g, st, x, d + e)[3] - evaluate(g, st, x, d - e)[3]) / (2 * h)
    # energies ~1e-1..1e1 mJ, h = 1e-6: round-off 1e-16 W / h ~ 1e-9 of the forces; truncation h^2
    assert np.abs(f - fd).max() < 1e-6 * np.abs(fd).max()
    if g.has_dir:
        assert np.abs(gd - gfd).max() < 1e-6 * np.abs(gfd).max()
        assert np.abs(m - np.cross(d, gd)).max() < 1e-12 * np.abs(m).max()


@pytest.mark.parametrize("section", ALL)
def test_curved_reference_is_stress_free(section):
    """Requirement: a curved, distorted reference (z = 0.3 sin x) with its own nodal directors has zero energy
    and forces at rest (round-off) although its interpolated directors are neither unit nor normal between
    nodes: the deformation gradient is exactly I there by construction."""
    X, conn, ctype = patch(False, seed=7, curved=0.3)
    g, st = make(section, X, conn, ctype)
    f, gd, m, W = evaluate(g, st, X)
    assert abs(W) < 1e-20 and np.abs(f).max() < 1e-11 and np.abs(gd).max() < 1e-11
    assert np.abs(g.F - np.eye(3)).max() < 1e-13


@pytest.mark.parametrize("triangles", MESHES, ids=["quad", "tri"])
def test_lumped_masses_and_inertia(triangles):
    """Requirement: lumped masses sum to rho h A, triangles put A/3 on each node (1e-12), and the rotational
    inertia is at least the physical rho h^3/12 per area."""
    X, conn, ctype = patch(triangles, seed=8)
    g, st = make("sm", X, conn, ctype)
    m = g.mass(g.rho)
    h, rho = SECTIONS["sm"]["thickness"], 1e-9
    assert m.sum() == pytest.approx(rho * h * g.area.sum(), rel=1e-12)
    if triangles:
        assert np.allclose(m[:, 0], rho * h * g.area / 3, rtol=1e-12)
        assert np.allclose(m[:, 2] + m[:, 3], rho * h * g.area / 3, rtol=1e-12)
    assert (g.inertia(g.rho) >= m * h**2 / 12 * (1 - 1e-12)).all()
    assert g.added_rotational_inertia >= 0.0


def test_orientation_of_fibres_follows_the_section_and_the_element_normal():
    """Requirement: warp lies along the projected reference direction turned by warp_angle about the element
    normal taken on the side of the orientation normal, whatever the node order (1e-12)."""
    from fdeck.deck.section import Orientation

    X, conn, ctype = patch(False, seed=9)
    for flip in (False, True):
        c = conn[:, ::-1] if flip else conn
        g, _ = make("membrane", X, c, ctype, orientation=Orientation(warp_angle=30.0))
        warp = g.frame[:, 0]
        assert np.abs(warp - [math.cos(math.radians(30)), math.sin(math.radians(30)), 0]).max() < 1e-12
