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
    collapsed halves included (1e-12), and no force at the nodes inside the block (1e-10 of the largest force:
    round-off of sums of ~64 terms), for full, fbar and reduced integration."""
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
    old = "divisions: [16, 16, 1], lattice: diagonal}"
    assert old in text
    deck.write_text(text.replace(old, "divisions: [17, 16, 1], lattice: diagonal}"))
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
    linear triangles with both inner edges chords too) and 10 % for the higher terms; on a grid of the same element
    size along x and y the fibres are stretched at first order (measured 117x more here), which a fibre 10^4 times
    stiffer than the shear turns into the locking."""
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


def test_fibre_bending_finds_its_neighbours_on_the_lattice():
    """Requirement: `fibre_bending` (local fibre curvature from neighbouring elements) works on the lattice it is
    needed for: with fibres at +-45 deg every element's neighbour along a family is the element centred one
    lattice step d (1, 1) or d (-1, 1) away, exactly the pairs of diamond centres (halves included) that the
    combinatorics of the lattice give; each half has a neighbour on one side per family and a free edge at the
    block's side (its collapsed face has no normal: no NaN, no refusal); per layer, so nz = 2 doubles the pairs."""
    from fdeck.physics.effects.fibre_bending import fibre_neighbours

    nx, ny, d = 8, 6, 3.0
    m = diagonal_block([0, 0, 0], [nx * d, ny * d, 2.0], [nx, ny, 2])
    X, conn = m.X, m.cells["hexahedron"]
    f1, f2 = np.array([1.0, 1.0, 0.0]) / math.sqrt(2), np.array([-1.0, 1.0, 0.0]) / math.sqrt(2)
    frame = np.broadcast_to(np.stack([f1, f2, [0.0, 0.0, 1.0]]), (len(conn), 3, 3)).copy()
    centre = X[conn].mean(axis=1)
    is_half = np.array([len(set(r)) < 8 for r in conn])
    centres = {(i, j) for i in range(nx + 1) for j in range(ny + 1) if (i + j) % 2}
    for family, step in ((0, (1, 1)), (1, (-1, 1))):
        nb = fibre_neighbours(X, conn, frame, family)
        expected = sum((i + step[0], j + step[1]) in centres for i, j in centres)
        assert (nb[:, 1] >= 0).sum() == 2 * expected  # two layers
        has = nb[:, 1] >= 0
        offset = centre[nb[has, 1]] - centre[has]
        # a half's centroid is not its diamond's centre: check the lattice step on diamond pairs only
        both = ~is_half[has] & ~is_half[nb[has, 1]]
        assert np.abs(offset[both] - d * np.array([*step, 0.0])).max() < 1e-12
        assert np.all((nb[is_half] >= 0).sum(axis=1) == 1)


@pytest.mark.parametrize("face", ["zmin", "zmax"])
def test_contact_areas_on_the_lattice_are_the_faces_shares(face):
    """Requirement: the tributary areas (normal to the face) contact gives the nodes of a lattice face are a quarter
    of each diamond (2 d^2) and a third of each half (a triangle, d^2) at each of their corners, whichever corner
    the halves' collapse falls on and on either face (1e-12 relative: sums of exact products); they add up to the
    block's face (nx d x ny d). Before collapsed faces were turned, 19-21 of the 32 nodes were off by up to 25 %."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck

    nx, ny, d = 8, 6, 2.5
    z = 0.0 if face == "zmin" else 1.0
    deck = {"mesh": {"block": {"size": [nx * d, ny * d, 1.0], "divisions": [nx, ny, 1], "lattice": "diagonal"}},
            "materials": {"m": {"type": "linear_elastic", "density": 1e-6, "youngs_modulus": 1000.0,
                                "poisson_ratio": 0.3}},
            "sections": [{"material": "m", "formulation": "full"}],
            "tools": {"t": {"surface": {"shape": "plane", "point": [0, 0, z + (-1 if z == 0 else 1)],
                                        "normal": [0, 0, 1 if z == 0 else -1]}}},
            "contact": [{"tool": "t", "nodes": face, "normal": {"law": "linear", "stiffness": 10.0}}],
            "steps": [{"duration": 1e-3}]}
    problem = compile_deck(Deck.model_validate(deck))
    contact = next(e for e in problem.effects if e.name == "contact:t")
    expected = {}
    for i in range(nx + 1):
        for j in range(ny + 1):
            if (i + j) % 2 == 0:
                continue
            corners = [(i + a, j + b) for a, b in ((1, 0), (0, 1), (-1, 0), (0, -1))
                       if 0 <= i + a <= nx and 0 <= j + b <= ny]
            share = 2 * d * d / 4 if len(corners) == 4 else d * d / 3
            for c in corners:
                expected[c] = expected.get(c, 0.0) + share
    # the area vector's z component: nodes on the block's sides also carry their side faces' x / y components
    got = {(round(x / d), round(y / d)): abs(a) for (x, y, _), a in zip(problem.X[contact.nodes], contact.vec[:, 2])}
    assert got.keys() == expected.keys()
    assert np.array([got[k] for k in expected]) == pytest.approx(np.array(list(expected.values())), rel=1e-12)
    assert sum(got.values()) == pytest.approx(nx * d * ny * d, rel=1e-12)


def test_collapsed_prisms_lump_their_mass_by_corner_and_other_degenerate_hexahedra_are_refused():
    """Requirement: a half (a prism) of the lattice gives each of its six distinct nodes a sixth of its mass for
    every formulation (the one-point `reduced` included: V0 / 8 per slot would give the repeated node a quarter;
    1e-12 relative), and the relaxed corner check admits collapsed hexahedra only: the same triangle with its
    fourth corner a mid-side node (a straight angle, no node repeated) stays refused (detJ_min <= 0)."""
    m = diagonal_block([0, 0, 0], [4.0, 4.0, 1.0], [2, 2, 1])  # four halves only
    conn = m.cells["hexahedron"]
    for form in ("full", "fbar", "reduced"):
        g = make_group(form, "neo_hookean", m.X, conn)
        per_node = np.zeros(len(m.X))
        np.add.at(per_node, conn, g.mass(np.ones(len(conn))))
        V = 4.0 * 4.0 * 1.0
        # every node is a corner of one or two halves, each giving it V_half / 6
        counts = np.zeros(len(m.X))
        for row in conn:
            counts[np.unique(row)] += 1
        assert per_node == pytest.approx(counts * (V / 4) / 6, rel=1e-12), form
    X = np.array([[0, -1, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [0, -1, 1], [1, 0, 1], [0, 1, 1], [0, 0, 1]], float)
    straight = np.arange(8)[None, :]
    assert hex8.prepare(X, straight)["detJ_min"][0] <= 0
    collapsed = np.array([[0, 1, 2, 2, 4, 5, 6, 6]])
    assert hex8.prepare(X, collapsed)["detJ_min"][0] > 0
    cube = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], float)
    pyramid = np.array([[0, 1, 2, 3, 4, 4, 4, 4]])  # a repeated node, but not a prism
    assert hex8.prepare(cube, pyramid)["detJ_min"][0] <= 0


def test_unequal_spacings_and_centroids_of_the_halves():
    """Requirement: unequal spacings along x and y (edges not at +-45 deg) are refused at the block naming both
    spacings and divisions that fit; a half's centroid (element sets by box, the fibre table) is the mean of its
    three distinct corners (1e-12), not a mean that counts the repeated node twice."""
    from fdeck.compile.mesh import centroids

    with pytest.raises(CompileError) as info:
        diagonal_block([0, 0, 0], [60.0, 40.0, 1.0], [20, 20, 1])
    (path, message), = info.value.problems
    assert path == ("mesh", "block") and "3 and 2 mm" in message and "[20, 14, 1]" in message
    m = diagonal_block([0, 0, 0], [12.0, 12.0, 1.0], [4, 4, 1])
    conn = m.cells["hexahedron"]
    c = centroids(m.X, conn)
    for e in np.nonzero([len(set(r)) < 8 for r in conn])[0]:
        corners = np.unique(m.X[conn[e]], axis=0)
        assert len(corners) == 6
        assert c[e] == pytest.approx(corners.mean(axis=0), rel=1e-12)
