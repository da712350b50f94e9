"""Fibre-aligned bias-extension meshes of shells (Abaqus .inp, S4R quadrilaterals) for decks/coupons/bias_*.yaml.

The same diamond lattice as ``make_bias_mesh.py`` (element edges along the +-45 deg fibres: fibre-misaligned
meshes lock; whole diamonds whose centre lies inside [0, W]; grips hold every node beyond the free length), in the
plane z = 0, one shell layer. Sets: nodes GRIP_LOW (y <= 0), GRIP_HIGH (y >= H); elements CENTRE (centroid within
W/8 of the sample centre in |dx| + |dy|), ALL.

    python decks/meshes/make_bias_shell_mesh.py   # writes bias_shell_w30_h120_n12.inp beside this file
"""

from __future__ import annotations

from pathlib import Path


from make_bias_mesh import diamond_mesh, write_inp as write_lattice_inp


def shell_mesh(W: float, H: float, n: int):
    """-> (points (n_node, 3), quads (n_el, 4), node sets, element sets), counter-clockwise seen from +z."""
    pts, hexes, node_sets, elem_sets = diamond_mesh(W, H, n, thickness=1.0, grip=W / n)
    nn = len(pts) // 2
    return pts[:nn], hexes[:, :4], {k: v[v < nn] for k, v in node_sets.items()}, elem_sets


def write_inp(path: Path, pts, quads, node_sets, elem_sets) -> None:
    """The mesh of ``shell_mesh`` as an Abaqus .inp of S4R shells."""
    write_lattice_inp(path, pts, quads, node_sets, elem_sets, element_type="S4R",
                      heading="fdeck bias-extension shell mesh")


if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    for W, H, n in ((30.0, 120.0, 12),):
        mesh = shell_mesh(W, H, n)
        name = f"bias_shell_w{W:g}_h{H:g}_n{n}.inp"
        write_inp(here / name, *mesh)
        print(f"{name}: {len(mesh[1])} quadrilaterals, {len(mesh[0])} nodes, centre {len(mesh[3]['CENTRE'])} elements")
