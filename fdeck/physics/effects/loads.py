"""External loads: gravity (body force from the physical, unscaled mass) and nodal forces."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from fdeck.deck.base import Card
from fdeck.engine.effect import Effect
from fdeck.registry import EffectKind, register_effect

Vector = tuple[float, float, float]


class Gravity(Card):
    """Uniform acceleration field on every node [mm/s^2]; 9810 mm/s^2 is standard gravity in mm-t-s."""

    type: Literal["gravity"]
    acceleration: Vector = Field(description="Acceleration vector [mm/s^2], e.g. [0, 0, -9810].")
    amplitude: str = Field("constant", description="Amplitude name (see boundary `displacement`).")


class NodalForce(Card):
    """Concentrated forces on the nodes of a set [N]."""

    type: Literal["nodal_force"]
    nodes: str = Field(description="Node set name.")
    force: Vector = Field(description="Force vector [N].")
    distribution: Literal["per_node", "total"] = Field(
        "per_node", description="per_node: every node gets `force`; total: `force` is split equally over the set.")
    amplitude: str = Field("smooth", description="Amplitude name (see boundary `displacement`).")


class BodyForce(Effect):
    ledger = "external"

    def __init__(self, name, nodes, per_node, amplitude):
        self.name, self.nodes, self.per_node, self.amplitude = name, nodes, per_node, amplitude

    def add_force(self, t, x, v, f):
        f[self.nodes] += self.amplitude(t) * self.per_node


def build_gravity(card, ctx):
    per_node = ctx.physical_mass[:, None] * np.asarray(card.acceleration)[None, :]
    return BodyForce("gravity", np.arange(len(ctx.X)), per_node, ctx.amplitude(card.amplitude))


def build_nodal_force(card, ctx):
    nodes = ctx.node_set(card.nodes)
    force = np.asarray(card.force, float)
    if card.distribution == "total":
        force = force / len(nodes)
    return BodyForce(f"nodal_force:{card.nodes}", nodes, np.tile(force, (len(nodes), 1)),
                     ctx.amplitude(card.amplitude))


register_effect(EffectKind("gravity", Gravity, build_gravity, "loads"))
register_effect(EffectKind("nodal_force", NodalForce, build_nodal_force, "loads"))
