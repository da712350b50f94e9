"""Symmetry plane: the fixed-dof constraint of ``physics.effects.boundary`` on the dofs a mirror plane holds.

A plane normal to axis a holds the translation along a and, on nodes with rotations (shell directors), the two
rotations about the in-plane axes (normal x: x, ry, rz): the field equals its mirror image, which flips the normal
component of a displacement and the in-plane components of a rotation (a pseudovector), so those vanish on it.
The compile check asks every node of the set to lie on one plane normal to a in the reference configuration:
within 1e-6 of the model's largest bounding-box extent of the plane through the set's lower median coordinate.
"""

from __future__ import annotations

import numpy as np

from fdeck.cards.boundary import Fixed
from fdeck.compile.errors import CompileError
from fdeck.physics.effects import boundary
from fdeck.registry import EffectKind, register_effect

AXIS = {"x": 0, "y": 1, "z": 2}
HELD_ROTATIONS = {"x": ["ry", "rz"], "y": ["rx", "rz"], "z": ["rx", "ry"]}
RELATIVE_TOLERANCE = 1e-6  # of the model size: far above round-off of generated or read coordinates


def off_plane(X: np.ndarray, nodes: np.ndarray, axis: int) -> tuple[float, float, float, np.ndarray]:
    """(spread [mm], plane coordinate [mm], tolerance [mm], node indices farther than the tolerance from the plane,
    farthest first, then in mesh order) of the set ``nodes`` (k,) of X (n_node, 3) along ``axis``; the plane is at
    the set's lower median coordinate (a coordinate of one of its nodes: with two equal groups, the lower one)."""
    c = X[nodes, axis]
    size = float(np.ptp(X, axis=0).max())
    tol = RELATIVE_TOLERANCE * size
    plane = float(np.sort(c)[(len(c) - 1) // 2])
    d = np.abs(c - plane)
    order = np.argsort(-d, kind="stable")
    return float(np.ptp(c)), plane, tol, nodes[order[d[order] > tol]]


def build(card, ctx):
    nodes = ctx.node_set(card.nodes)
    if len(nodes) == 0:
        raise CompileError([(ctx.path + ("nodes",), f"node set '{card.nodes}' is empty")])
    axis = AXIS[card.normal]
    spread, plane, tol, off = off_plane(ctx.X, nodes, axis)
    if len(off):
        raise CompileError([(ctx.path + ("nodes",), (
            f"the nodes of set '{card.nodes}' are not on one plane normal to {card.normal}: their {card.normal} "
            f"coordinates spread over {spread:.6g} mm (allowed {tol:.3g} mm, 1e-6 of the model size); {len(off)} "
            f"nodes lie off the plane {card.normal} = {plane:.6g}, e.g. nodes (1-based, in mesh order) "
            f"{(off[:5] + 1).tolist()}"))])
    dofs = [card.normal]
    rotations = ctx.rotations
    if rotations is not None and len(np.intersect1d(nodes, rotations.nodes)):
        dofs += HELD_ROTATIONS[card.normal]
    effect = boundary.build(Fixed(type="fixed", nodes=card.nodes, dofs=dofs), ctx)
    effect.name = f"symmetry:{card.nodes}"
    return effect


register_effect(EffectKind("symmetry", build))
