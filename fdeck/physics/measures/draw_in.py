"""Draw-in of a blank edge: how far its nodes moved inward, in the plane normal to the punch axis [mm].

For each node a of the edge set, the inward direction is the unit vector n_a from the node towards the centre C
(deck ``centre``, default the centroid of every mesh node in the reference configuration), both projected on the
plane normal to ``axis``; the draw-in is d_a = (x_a - X_a) . n_a, positive when the edge is pulled in. The
measure records the mean and the largest d_a over the set (``<name>_mean``, ``<name>_max``). Radial from the
centre suits a round or square blank drawn into a central die; the displacement along the axis never counts.
"""

from __future__ import annotations

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.registry import MeasureKind, register_measure


class Measure:
    def __init__(self, card, nodes, X, inward):
        self.columns = [f"{card.name}_mean", f"{card.name}_max"]
        self.nodes, self.X0, self.inward = nodes, X[nodes], inward  # inward (n, 3) unit, normal to the axis

    def evaluate(self, x, v):
        d = np.einsum("ij,ij->i", x[self.nodes] - self.X0, self.inward)
        return [float(d.mean()), float(d.max())]


def build(card, ctx):
    nodes = ctx.node_set(card.nodes)
    axis = "xyz".index(card.axis)
    centre = ctx.X.mean(axis=0) if card.centre is None else np.asarray(card.centre, float)
    to_c = centre - ctx.X[nodes]
    to_c[:, axis] = 0.0
    length = np.linalg.norm(to_c, axis=1)
    if np.any(length <= 1e-9 * max(1.0, float(np.abs(ctx.X).max()))):
        bad = nodes[length <= 1e-9 * max(1.0, float(np.abs(ctx.X).max()))]
        raise CompileError([(ctx.path + ("nodes",), f"nodes {bad[:10].tolist()} lie on the axis through the centre: "
                             "no inward direction")])
    return Measure(card, nodes, ctx.X, to_c / length[:, None])


register_measure(MeasureKind("draw_in", build))
