"""Fibre-aligned bias-extension meshes (Abaqus .inp) for decks/bias_extension_3weave*.yaml.

The sample is W wide with a free length H between the grips, fibres at +-45 deg to the pull (y). Element edges run
along the fibres (MODELS 6.1: fibre-misaligned meshes lock), so the mesh is a lattice of square "diamonds" whose
diagonal d = W / n. A rectangle cannot be tiled by whole diamonds: whole diamonds whose centre lies inside
[0, W] are kept, so the free edges zig-zag at the mesh scale (their fibres carry no load: the ends are free), and
the lattice extends 'grip' mm beyond each end of the free length, where the grips hold every node.
[P]'s meshes have element diagonals W/6 (edge 11.78 mm) and W/20 (3.53 mm) for W = 100 mm.

Sets written: nodes GRIP_LOW (y <= 0), GRIP_HIGH (y >= H); elements CENTRE (centroid within W/8 of the sample
centre in |dx| + |dy|: the inner part of the uniformly sheared zone C), ALL.

    python decks/meshes/make_bias_mesh.py   # writes bias_w100_n6.inp and bias_w100_n20.inp beside this file
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def diamond_mesh(W: float, H: float, n: int, thickness: float, grip: float):
    """-> (points (n_node, 3), hexahedra (n_el, 8), node sets, element sets)."""
    d = W / n  # diamond diagonal; lattice nodes at (i d/2, j d/2) with i + j even
    h = d / 2
    jmin, jmax = int(np.floor(-grip / h)), int(np.ceil((H + grip) / h))
    cells, index = [], {}

    def node(i, j):
        return index.setdefault((i, j), len(index))

    for jc in range(jmin + 1, jmax):  # diamond centres at (ic h, jc h), ic + jc odd
        for ic in range(-1, 2 * n + 2):
            if (ic + jc) % 2 == 0 or not (0.0 <= ic * h <= W):
                continue
            # counter-clockwise seen from +z: bottom, right, top, left vertices
            quad = [node(ic, jc - 1), node(ic + 1, jc), node(ic, jc + 1), node(ic - 1, jc)]
            cells.append(quad)
    ij = np.array(sorted(index, key=index.get), float)
    plane = np.column_stack([ij[:, 0] * h, ij[:, 1] * h])
    nn = len(plane)
    pts = np.vstack([np.column_stack([plane, np.zeros(nn)]), np.column_stack([plane, np.full(nn, thickness)])])
    quads = np.array(cells)
    hexes = np.hstack([quads, quads + nn])
    y = pts[:, 1]
    node_sets = {"GRIP_LOW": np.nonzero(y <= 1e-9)[0], "GRIP_HIGH": np.nonzero(y >= H - 1e-9)[0]}
    c = pts[hexes].mean(axis=1)
    centre = np.nonzero(np.abs(c[:, 0] - W / 2) + np.abs(c[:, 1] - H / 2) <= W / 8 + 1e-9)[0]
    return pts, hexes, node_sets, {"CENTRE": centre}


def write_inp(path: Path, pts, cells, node_sets, elem_sets, element_type: str = "C3D8",
              heading: str = "fdeck bias-extension mesh") -> None:
    """Abaqus .inp: nodes, the cells as element set ALL of ``element_type``, then the node and element sets."""
    lines = ["*HEADING", f"{heading} {path.name}", "*NODE"]
    lines += [f"{i + 1}, {p[0]:.10g}, {p[1]:.10g}, {p[2]:.10g}" for i, p in enumerate(pts)]
    lines.append(f"*ELEMENT, TYPE={element_type}, ELSET=ALL")
    lines += [f"{e + 1}, " + ", ".join(str(v + 1) for v in c) for e, c in enumerate(cells)]
    for name, ids in node_sets.items():
        lines.append(f"*NSET, NSET={name}")
        lines += [", ".join(str(i + 1) for i in ids[k: k + 16]) for k in range(0, len(ids), 16)]
    for name, ids in elem_sets.items():
        lines.append(f"*ELSET, ELSET={name}")
        lines += [", ".join(str(i + 1) for i in ids[k: k + 16]) for k in range(0, len(ids), 16)]
    path.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    here = Path(__file__).resolve().parent
    for n in (6, 20):
        mesh = diamond_mesh(W=100.0, H=200.0, n=n, thickness=2.54, grip=100.0 / n)
        write_inp(here / f"bias_w100_n{n}.inp", *mesh)
        print(f"bias_w100_n{n}.inp: {len(mesh[1])} hexahedra, {len(mesh[0])} nodes, "
              f"centre {len(mesh[3]['CENTRE'])} elements")
