"""External loads: gravity (body force from the physical, unscaled mass), nodal forces and nodal moments."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from fdeck.compile.errors import CompileError
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
    forces = "external"

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


class NodalMoment(Card):
    """Concentrated moments on the shell nodes of a set [N mm], fixed in direction (not following the rotation).
    Only the part normal to each node's current director acts: a shell node has no drilling stiffness, so a
    component about the director could only spin it (it does no work on the director)."""

    type: Literal["nodal_moment"]
    nodes: str = Field(description="Node set name (its nodes with rotations, i.e. shell nodes, are loaded).")
    moment: Vector = Field(description="Moment vector [N mm] about the global axes.")
    distribution: Literal["per_node", "total"] = Field(
        "per_node", description="per_node: every node gets `moment`; total: `moment` is split equally over the set.")
    amplitude: str = Field("smooth", description="Amplitude name (see boundary `displacement`).")


class Moment(Effect):
    """External moments into the rotational state (its work enters the ledger through the rotation increments)."""

    forces = "external"
    rotational = True

    def __init__(self, name, nodes, per_node, amplitude):
        self.name, self.nodes, self.per_node, self.amplitude = name, nodes, per_node, amplitude
        self.rot = None

    def bind(self, rotations) -> None:
        self.rot = rotations

    def add_force(self, t, x, v, f):
        m = self.amplitude(t) * self.per_node
        d = self.rot.d[self.nodes]
        self.rot.m_ext[self.nodes] += m - np.einsum("ni,ni->n", m, d)[:, None] * d


def build_nodal_moment(card, ctx):
    nodes = ctx.node_set(card.nodes)
    rotations = ctx.rotations
    carriers = np.intersect1d(nodes, rotations.nodes) if rotations is not None else np.zeros(0, np.int64)
    if len(carriers) == 0:
        raise CompileError([(ctx.path + ("nodes",), f"set '{card.nodes}' has no node with rotations (shell nodes)")])
    moment = np.asarray(card.moment, float)
    if card.distribution == "total":
        moment = moment / len(carriers)
    return Moment(f"nodal_moment:{card.nodes}", carriers, np.tile(moment, (len(carriers), 1)),
                  ctx.amplitude(card.amplitude))


register_effect(EffectKind("gravity", Gravity, build_gravity, "loads"))
register_effect(EffectKind("nodal_force", NodalForce, build_nodal_force, "loads"))
register_effect(EffectKind("nodal_moment", NodalMoment, build_nodal_moment, "loads"))
