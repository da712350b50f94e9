"""Kinematic boundary conditions: fixed dofs, prescribed displacement, prescribed velocity."""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from fdeck.deck.base import Card
from fdeck.engine.effect import Effect
from fdeck.registry import EffectKind, register_effect

Dof = Literal["x", "y", "z"]
DOF_INDEX = {"x": 0, "y": 1, "z": 2}


class Fixed(Card):
    """Zero velocity on the given dofs of a node set for the whole run."""

    type: Literal["fixed"]
    nodes: str = Field(description="Node set name.")
    dofs: list[Dof] = Field(default=["x", "y", "z"], min_length=1, description="Constrained directions.")


class Displacement(Card):
    """Prescribed displacement u(t) = value * amplitude(t) on the given dofs [mm]."""

    type: Literal["displacement"]
    nodes: str = Field(description="Node set name.")
    dofs: list[Dof] = Field(min_length=1, description="Prescribed directions.")
    value: float = Field(description="Displacement at amplitude 1 [mm].")
    amplitude: str = Field("smooth", description="Amplitude name; built-ins: constant, ramp, smooth (0 -> 1 over "
                           "the whole run), or a name from `amplitudes`.")


class Velocity(Card):
    """Prescribed velocity v(t) = value * amplitude(t) on the given dofs [mm/s]."""

    type: Literal["velocity"]
    nodes: str = Field(description="Node set name.")
    dofs: list[Dof] = Field(min_length=1, description="Prescribed directions.")
    value: float = Field(description="Velocity at amplitude 1 [mm/s].")
    amplitude: str = Field("constant", description="Amplitude name (see `displacement`).")


class Prescribed(Effect):
    """Sets v on (nodes, dofs) at each half step; ``mode`` 'displacement' aims at u(t_next) exactly."""

    constrains = True

    def __init__(self, name, nodes, dofs, value, amplitude, mode, X):
        self.name, self.nodes, self.dofs = name, nodes, np.array(dofs)
        self.value, self.amplitude, self.mode = value, amplitude, mode
        self.X = X[nodes][:, self.dofs]

    def constrain(self, t_next, dt, x, v):
        idx = np.ix_(self.nodes, self.dofs)
        if self.mode == "fixed":
            v[idx] = 0.0
        elif self.mode == "velocity":
            v[idx] = self.value * self.amplitude(t_next - 0.5 * dt)
        else:
            target = self.X + self.value * self.amplitude(t_next)
            v[idx] = (target - x[idx]) / dt


def build(card, ctx):
    dofs = [DOF_INDEX[d] for d in card.dofs]
    nodes = ctx.node_set(card.nodes)
    if card.type == "fixed":
        return Prescribed(f"fixed:{card.nodes}", nodes, dofs, 0.0, None, "fixed", ctx.X)
    amp = ctx.amplitude(card.amplitude)
    return Prescribed(f"{card.type}:{card.nodes}", nodes, dofs, card.value, amp, card.type, ctx.X)


for _card in (Fixed, Displacement, Velocity):
    register_effect(EffectKind(_card.model_fields["type"].annotation.__args__[0], _card, build, "boundary"))
