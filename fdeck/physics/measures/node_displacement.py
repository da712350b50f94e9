"""Displacement of a node set (mean, min or max of one component): tip deflections, clamp travel."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from fdeck.deck.base import Card
from fdeck.registry import MeasureKind, register_measure


class NodeDisplacement(Card):
    """A component of the displacement [mm] of a node set, reduced to one number."""

    type: Literal["node_displacement"]
    name: str = Field(description="Column name in history.csv and key in summary.json.")
    nodes: str = Field(description="Node set name.")
    component: Literal["x", "y", "z", "magnitude"] = "z"
    reduce: Literal["mean", "min", "max"] = "mean"


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


register_measure(MeasureKind("node_displacement", NodeDisplacement, build))
