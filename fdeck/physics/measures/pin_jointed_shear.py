"""Shear angle of the central zone of a bias-extension test predicted by the pin-jointed net (MODELS 6.1).

gamma(d) = pi/2 - 2 arccos((D + d) / (sqrt(2) D)), D = H - W, d the clamp travel read from a node set. Recorded
beside the simulated central shear angle (an ``element_average`` of ``shear_angle``) so that the history and the
summary show theory and simulation side by side.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.registry import MeasureKind, register_measure




def shear_angle(d: float, W: float, H: float) -> float:
    """Pin-jointed central shear angle [deg] at clamp travel d [mm]; nan beyond full locking."""
    D = H - W
    c = (D + d) / (math.sqrt(2.0) * D)
    return math.degrees(math.pi / 2 - 2 * math.acos(c)) if c <= 1.0 else float("nan")


class Measure:
    def __init__(self, card, nodes, X):
        self.columns = [card.name]
        self.card, self.nodes, self.axis = card, nodes, "xyz".index(card.axis)
        self.X0 = X[nodes, self.axis]

    def evaluate(self, x, v):
        d = float(np.mean(x[self.nodes, self.axis] - self.X0))
        return [shear_angle(d, self.card.width, self.card.free_length)]


def build(card, ctx):
    return Measure(card, ctx.node_set(card.clamp), ctx.X)


register_measure(MeasureKind("pin_jointed_shear", build))
