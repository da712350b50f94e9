"""Displacement of a node set (mean, min or max of one component): tip deflections, clamp travel."""

from __future__ import annotations


import numpy as np

from fdeck.registry import MeasureKind, register_measure




class Measure:
    def __init__(self, card, nodes, X):
        self.columns = [card.name]
        self.nodes, self.X0 = nodes, X[nodes]
        self.axis = "xyz".find(card.component)
        self.reduce = getattr(np, card.reduce)

    def evaluate(self, x, v):
        u = x[self.nodes] - self.X0
        c = np.linalg.norm(u, axis=1) if self.axis < 0 else u[:, self.axis]
        return [float(self.reduce(c))]


def build(card, ctx):
    return Measure(card, ctx.node_set(card.nodes), ctx.X)


register_measure(MeasureKind("node_displacement", build))
