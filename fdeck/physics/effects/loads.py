"""External loads: gravity (body force from the physical, unscaled mass), nodal forces and nodal moments."""

from __future__ import annotations


import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.registry import EffectKind, register_effect







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


register_effect(EffectKind("gravity", build_gravity))
register_effect(EffectKind("nodal_force", build_nodal_force))
register_effect(EffectKind("nodal_moment", build_nodal_moment))
