"""Kinematic boundary conditions: fixed dofs, prescribed displacement, prescribed velocity.

Translational dofs x, y, z act on every node of the set. Rotational dofs rx, ry, rz (rotation about the global
axes) act on the nodes of the set that carry a director (shell nodes; solid-only nodes have no rotations): a clamp
is ``dofs: [x, y, z, rx, ry, rz]``, a symmetry plane normal to x is ``dofs: [x, ry, rz]``. A rotational
``velocity`` prescribes the angular velocity component [rad/s]; a rotational ``displacement`` prescribes the angle
[rad] about that axis, integrated from the angular velocity (the rotation about a fixed axis when the set's other
rotational dofs are fixed).
"""

from __future__ import annotations


import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.registry import EffectKind, register_effect
from fdeck.cards.boundary import DOF_INDEX









class Prescribed(Effect):
    """Sets v on (nodes, dofs) at each half step; ``mode`` 'displacement' aims at u(t_next) exactly."""

    constrains = True

    def __init__(self, name, nodes, dofs, value, amplitude, mode, X):
        self.name, self.nodes, self.dofs = name, nodes, np.array(dofs)
        self.value, self.amplitude, self.mode = value, amplitude, mode
        self.X = X[nodes][:, self.dofs]
        self.idx = np.ix_(self.nodes, self.dofs)  # built once: np.ix_ per call cost ~10 us a constraint a cycle

    def constrain(self, t_next, dt, x, v):
        idx = self.idx
        if self.mode == "fixed":
            v[idx] = 0.0
        elif self.mode == "velocity":
            v[idx] = self.value * self.amplitude(t_next - 0.5 * dt)
        else:
            target = self.X + self.value * self.amplitude(t_next)
            v[idx] = (target - x[idx]) / dt


class PrescribedRotation(Effect):
    """Sets the angular velocity on (nodes, axes) at each half step; 'displacement' aims at the angle at t_next,
    the angle being the integral of the prescribed angular velocity component since the start."""

    constrains = True
    rotational = True

    def __init__(self, name, nodes, axes, value, amplitude, mode):
        self.name, self.nodes, self.axes = name, nodes, np.array(axes)
        self.value, self.amplitude, self.mode = value, amplitude, mode
        self.angle = np.zeros((len(nodes), len(axes)))
        self.idx = np.ix_(self.nodes, self.axes)
        self.rot = None

    def bind(self, rotations) -> None:
        self.rot = rotations
        self.angle[:] = 0.0

    def constrain(self, t_next, dt, x, v):
        idx = self.idx
        if self.mode == "fixed":
            self.rot.w[idx] = 0.0
            return
        if self.mode == "velocity":
            w = np.full(self.angle.shape, self.value * self.amplitude(t_next - 0.5 * dt))
        else:
            w = (self.value * self.amplitude(t_next) - self.angle) / dt
        self.rot.w[idx] = w
        self.angle += dt * w

    def probe(self, x, v):
        pass  # no translational dof; ``constrain`` would advance the angle and write the rotations


class Both(Effect):
    """A translational and a rotational constraint from one card (applied in that order)."""

    constrains = True
    rotational = True

    def __init__(self, name, parts):
        self.name, self.parts = name, parts

    def bind(self, rotations) -> None:
        self.parts[1].bind(rotations)

    def constrain(self, t_next, dt, x, v):
        for p in self.parts:
            p.constrain(t_next, dt, x, v)

    def probe(self, x, v):
        for p in self.parts:
            p.probe(x, v)


def build(card, ctx):
    nodes = ctx.node_set(card.nodes)
    idx = [DOF_INDEX[d] for d in card.dofs]
    trans, rot = [i for i in idx if i < 3], [i - 3 for i in idx if i >= 3]
    amp = None if card.type == "fixed" else ctx.amplitude(card.amplitude)
    value = 0.0 if card.type == "fixed" else card.value
    name = f"{card.type}:{card.nodes}"
    parts = []
    if trans:
        parts.append(Prescribed(name, nodes, trans, value, amp, card.type, ctx.X))
    if rot:
        rotations = ctx.rotations
        carriers = np.intersect1d(nodes, rotations.nodes) if rotations is not None else np.zeros(0, np.int64)
        if len(carriers) == 0:
            raise CompileError([(ctx.path + ("dofs",), f"rotational dofs need nodes with rotations (shell nodes); "
                                 f"set '{card.nodes}' has none")])
        parts.append(PrescribedRotation(name, carriers, rot, value, amp, card.type))
    return parts[0] if len(parts) == 1 else Both(name, parts)


for _name in ("fixed", "displacement", "velocity"):
    register_effect(EffectKind(_name, build))
