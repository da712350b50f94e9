"""Spurious-mode indicator: the largest short-wave ripple of a surface, in mm.

Nodes of a surface set are grouped into lines along ``along`` (same reference coordinate across). For every node
with two neighbours on each side of its line, a parabola is fitted by least squares through the five current
heights (component ``height``) against the reference position along the line; the indicator is the largest
|height - parabola| at the centre node. A smoothly bent surface is locally quadratic, so the indicator is of order
h^4 z'''' (about zero); a zig-zag (hourglass-like) pattern of amplitude A gives 48/35 A on a uniform line (the
five-point quadratic smoothing weights are (-3, 12, 17, 12, -3) / 35), whatever the mesh size.
This makes the indicator comparable between a 3 mm and a 1 mm mesh, unlike second differences divided by h.
"""

from __future__ import annotations


import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.registry import MeasureKind, register_measure




def windows(X: np.ndarray, nodes: np.ndarray, along: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """-> (index windows (n_w, 5) into x, reference abscissae (n_w, 5) centred on the middle node)."""
    across = [a for a in range(3) if a not in (along, height)][0]
    key = np.round(X[nodes, across], 6)
    win, s = [], []
    for k in np.unique(key):
        line = nodes[key == k]
        line = line[np.argsort(X[line, along])]
        for i in range(2, len(line) - 2):
            w = line[i - 2: i + 3]
            win.append(w)
            s.append(X[w, along] - X[line[i], along])
    return np.array(win, dtype=np.int64).reshape(-1, 5), np.array(s).reshape(-1, 5)


class Measure:
    def __init__(self, card, win, s):
        self.columns = [card.name]
        self.win, self.h = win, "xyz".index(card.height)
        V = np.stack([np.ones_like(s), s, s * s], axis=2)  # (n_w, 5, 3) Vandermonde
        # least-squares fit value at the centre (s = 0) is the first coefficient: row 0 of (V^T V)^-1 V^T
        self.centre_weights = np.linalg.solve(np.einsum("wki,wkj->wij", V, V), np.swapaxes(V, 1, 2))[:, 0, :]

    def evaluate(self, x, v):
        z = x[self.win, self.h]  # (n_w, 5)
        fit = np.einsum("wk,wk->w", self.centre_weights, z)
        return [float(np.abs(z[:, 2] - fit).max())]


def build(card, ctx):
    along, height = "xyz".index(card.along), "xyz".index(card.height)
    if along == height:
        raise CompileError([(ctx.path + ("height",), "`height` must differ from `along`")])
    win, s = windows(ctx.X, ctx.node_set(card.nodes), along, height)
    if len(win) == 0:
        raise CompileError([(ctx.path + ("nodes",), f"set '{card.nodes}' has no line of 5 or more nodes along "
                             f"{card.along}")])
    return Measure(card, win, s)


register_measure(MeasureKind("surface_waviness", build))
