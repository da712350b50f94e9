"""Shear angle of the central zone of a bias-extension test predicted by the pin-jointed net (MODELS 6.1).

gamma(d) = pi/2 - 2 arccos((D + d) / (sqrt(2) D)), D = H - W, d the clamp travel read from a node set. Recorded
beside the simulated central shear angle (an ``element_average`` of ``shear_angle``) so that the history and the
summary show theory and simulation side by side.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from fdeck.deck.base import Card
from fdeck.registry import MeasureKind, register_measure


class PinJointedShear(Card):
    """Kinematic (pin-jointed net) central shear angle [deg] of a bias-extension sample."""

    type: Literal["pin_jointed_shear"]
    name: str = Field(description="Column name in history.csv and key in summary.json.")
    clamp: str = Field(description="Node set of the moving clamp.")
    axis: Literal["x", "y", "z"] = Field("y", description="Pull direction.")
    width: float = Field(gt=0, description="Sample width W [mm].")
    free_length: float = Field(gt=0, description="Free length H between the clamps [mm] (H >= 2 W).")

    @model_validator(mode="after")
    def _long_enough(self):
        if self.free_length < 2 * self.width:
            raise ValueError("a bias-extension sample needs free_length >= 2 width")
        return self


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


register_measure(MeasureKind("pin_jointed_shear", PinJointedShear, build))
