"""The fibre-aligned block (``mesh.block.lattice: diagonal``, compile.mesh.diagonal_block): element counts of the
published +-45 meshes, volume, edge directions, the patch test through the half-diamonds at the sides, and why the
lattice exists: a fibre-inextensible shear field that a +-45 diamond mesh follows with second-order fibre strain and
a grid mesh only with first-order fibre strain (intra-ply shear locking)."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.compile.errors import CompileError
from fdeck.compile.mesh import block, diagonal_block
from fdeck.physics.elements import hex8

from helpers import DECKS, ROOT
from test_hex8 import internal_forces, make_group

QUARTER = ([0.0, 0.0, 0.1], [300.0, 300.0, 2.54])


@pytest.mark.parametrize("half_diagonals,published", [(100, 20_400), (200, 80_800)])
def test_quarter_blank_has_the_published_element_counts(half_diagonals, published):
    """Requirement: the +-45 double-dome quarter (300 x 300 mm, 4 layers) with 4.24 / 2.12 mm diamonds has the 20 400
    / 80 800 hexahedra of [P] (MODELS.md 6.4), and its element volumes sum to the block's (relative 1e-12: sums of
    exact products of the lattice spacing)."""
    m = diagonal_block(*QUARTER, [half_diagonals, half_diagonals, 4])
    conn = m.cells["hexahedron"]
    assert len(conn) == published
    V0 = hex8.prepare(m.X, conn)["V0"]
    assert V0.sum() == pytest.approx(300 * 300 * 2.54, rel=1e-12)
    assert V0.min() > 0


def test_inner_edges_run_along_the_fibres_and_halves_close_the_sides():
    """Requirement: with equal spacings d every bottom-face edge is at +-45 deg with length d sqrt(2) =
    element_size (1e-12), or lies on a side of the block with length 2 d, or is collapsed (length 0, exactly one
    per half); the halves are the nx + ny elements centred on the sides, the diamonds the 22 points with i + j odd
    strictly inside the 10 x 6 lattice."""
    h = 4.0 * math.sqrt(2)
    m = diagonal_block([0, 0, 0], [40.0, 24.0, 1.0], element_size=h)  # d = 4 mm: nx = 10, ny = 6
    X, conn = m.X, m.cells["hexahedron"]
    assert len(conn) == 22 + (10 + 6)
    a, b = X[conn[:, :4]], X[np.roll(conn[:, :4], -1, axis=1)]
    e = (b - a)[..., :2]
    length = np.linalg.norm(e, axis=-1)
    collapsed = length == 0
    side = ~collapsed & (((e[..., 0] == 0) & np.isin(a[..., 0], [0.0, 40.0]))
                         | ((e[..., 1] == 0) & np.isin(a[..., 1], [0.0, 24.0])))
    fibre = ~collapsed & ~side
    assert sorted(collapsed.sum(axis=1)) == [0] * 22 + [1] * 16
    assert side.sum() == 16 and np.all(side.sum(axis=1) == collapsed.sum(axis=1))
    assert np.abs(np.abs(e[fibre][:, 0]) - np.abs(e[fibre][:, 1])).max() < 1e-12
    assert length[fibre] == pytest.approx(h, rel=1e-12)
    assert length[side] == pytest.approx(8.0, rel=1e-12)


def test_patch_test_through_the_half_diamonds():
    """Requirement: a homogeneous deformation x = A X gives F = A at every integration point of every element, the
    collapsed halves included (1e-12), and no force at the nodes inside the block (1e-10 of the largest force: round-off of
    sums of ~64 terms), for full, fbar and reduced integration."""
    m = diagonal_block([0, 0, 0], [8.0, 8.0, 2.0], [4, 4, 2])
    A = np.array([[1.02, 0.01, -0.005], [0.004, 0.99, 0.008], [0.0, 0.006, 1.015]])
    inside = np.nonzero(np.all((m.X > 1e-9) & (m.X < np.array([8.0, 8.0, 2.0]) - 1e-9), axis=1))[0]
    assert len(inside)
    for form in ("full", "fbar", "reduced"):
        g = make_group(form, "neo_hookean", m.X, m.cells["hexahedron"])
        f = internal_forces(g, m.X @ A.T + 1.0)
        assert np.abs(g.F - A).max() < 1e-12, form
        assert np.abs(f[inside]).max() < 1e-10 * np.abs(f).max(), form


def test_odd_divisions_are_refused_at_the_block(tmp_path):
    """Requirement: odd x or y divisions (the block's corners would be diamond centres) are refused at the deck's
    line with exit 2 by `fdeck validate`, and by the generator itself naming the key; never rounded silently."""
    deck = tmp_path / "odd.yaml"
    text = (DECKS / "forming" / "double_dome_45_coarse.yaml").read_text()
    old = "divisions: [12, 12, 1]}"
    assert old in text
    deck.write_text(text.replace(old, "divisions: [13, 12, 1], lattice: diagonal}"))
    r = subprocess.run([sys.executable, "-m", "fdeck.cli", "validate", str(deck)], capture_output=True, text=True,
                       cwd=ROOT, timeout=300)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    line = next(n for n, t in enumerate(deck.read_text().splitlines(), 1) if "lattice: diagonal" in t)
    assert f"{deck}:{line}:" in r.stderr and "even divisions" in r.stderr
    with pytest.raises(CompileError) as info:
        diagonal_block([0, 0, 0], [10.0, 10.0, 1.0], [5, 4, 1])
    (path, message), = info.value.problems
    assert path == ("mesh", "block", "divisions") and "even" in message


def _fibre_strain(X, conn, field):
    """Largest |stretch - 1| along the +-45 fibres over the 2x2x2 points of every element, for x = field(X)."""
    dN = hex8.prepare(X, conn)["dN"]
    F = np.einsum("eai,eqaj->eqij", field(X)[conn], dN)
    f1, f2 = np.array([1.0, 1.0, 0.0]) / math.sqrt(2), np.array([-1.0, 1.0, 0.0]) / math.sqrt(2)
    return max(np.abs(np.linalg.norm(F @ f, axis=-1) - 1).max() for f in (f1, f2))


def test_a_trellising_field_is_followed_by_the_fibre_aligned_mesh_only():
    """Requirement (why the lattice exists): x = alpha(a) + beta(b) in the fibre coordinates a, b (unit-speed
    curves: a Chebyshev net, the kinematics of a fabric shearing with inextensible fibres, shear varying with b)
    stretches no fibre. On the diamond lattice the elements interpolate it with fibre strain at most the chord's
    shortfall kappa^2 l^2 / 24 (l = 4.24 mm diamond edge, kappa the curve's curvature; the collapsed halves are
    linear triangles with both inner edges chords too) and 10 % for the higher terms; on a grid of the same element size along x and y the fibres are stretched at first order
    (measured 117x more here), which a fibre 10^4 times stiffer than the shear turns into the locking."""
    kappa = 0.01  # 1/mm: the fibre direction of beta turns 0.01 rad per mm, 0.6 rad over the 60 mm block

    def field(X):
        a = (X[:, 0] + X[:, 1]) / math.sqrt(2)
        b = (X[:, 1] - X[:, 0]) / math.sqrt(2)
        f1, f2 = np.array([1.0, 1.0]) / math.sqrt(2), np.array([-1.0, 1.0]) / math.sqrt(2)
        phi = kappa * b  # beta'(b) = f2 turned by phi(b): unit speed
        beta = np.stack([np.sin(phi), 1 - np.cos(phi)], 1) / kappa  # integral of (cos phi, sin phi) in (f2, -f1)
        xy = a[:, None] * f1 + beta[:, :1] * f2 - beta[:, 1:] * f1
        return np.column_stack([xy, X[:, 2]])

    l = 3.0 * math.sqrt(2)
    diamonds = diagonal_block([0, 0, 0], [60.0, 60.0, 1.0], [20, 20, 1])
    grid = block([0, 0, 0], [60.0, 60.0, 1.0], [14, 14, 1])  # 4.29 mm squares
    aligned = _fibre_strain(diamonds.X, diamonds.cells["hexahedron"], field)
    crossed = _fibre_strain(grid.X, grid.cells["hexahedron"], field)
    assert aligned <= 1.1 * kappa**2 * l**2 / 24
    assert crossed > 50 * aligned
