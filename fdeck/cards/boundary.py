"""Cards of the kinematic boundary conditions (`fixed`, `displacement`, `velocity`); effects in
`fdeck.physics.effects.boundary` (see its docstring for translational and rotational dofs)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


Dof = Literal["x", "y", "z", "rx", "ry", "rz"]


DOF_INDEX = {"x": 0, "y": 1, "z": 2, "rx": 3, "ry": 4, "rz": 5}


class Fixed(Card):
    """Zero velocity on the given dofs of a node set for the whole run."""

    type: Literal["fixed"]
    nodes: str = Field(description="Node set name.")
    dofs: list[Dof] = Field(default=["x", "y", "z"], min_length=1, description=(
        "Constrained directions: x, y, z (translations), rx, ry, rz (rotations of shell nodes)."))


class Displacement(Card):
    """Prescribed displacement u(t) = value * amplitude(t) on the given dofs [mm, or rad for rotations]."""

    type: Literal["displacement"]
    nodes: str = Field(description="Node set name.")
    dofs: list[Dof] = Field(min_length=1, description="Prescribed directions (x, y, z, rx, ry, rz).")
    value: float = Field(description="Displacement at amplitude 1 [mm] (rotation angle [rad] for rx, ry, rz).")
    amplitude: str = Field("smooth", description="Amplitude name; built-ins: constant, ramp, smooth (0 -> 1 over "
                           "the whole run), or a name from `amplitudes`.")


class Velocity(Card):
    """Prescribed velocity v(t) = value * amplitude(t) on the given dofs [mm/s, or rad/s for rotations]."""

    type: Literal["velocity"]
    nodes: str = Field(description="Node set name.")
    dofs: list[Dof] = Field(min_length=1, description="Prescribed directions (x, y, z, rx, ry, rz).")
    value: float = Field(description="Velocity at amplitude 1 [mm/s] (angular velocity [rad/s] for rx, ry, rz).")
    amplitude: str = Field("constant", description="Amplitude name (see `displacement`).")


for _card in (Fixed, Displacement, Velocity):
    register_card(CardEntry(_card.model_fields["type"].annotation.__args__[0], _card, "effect", "boundary"))
