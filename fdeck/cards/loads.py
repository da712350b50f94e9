"""Cards of the loads (`gravity`, `nodal_force`, `nodal_moment`); effects in `fdeck.physics.effects.loads`."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


Vector = tuple[float, float, float]


class Gravity(Card):
    """Uniform acceleration field on every node [mm/s^2]; 9810 mm/s^2 is standard gravity in mm-t-s."""

    type: Literal["gravity"]
    acceleration: Vector = Field(description="Acceleration vector [mm/s^2], e.g. [0, 0, -9810].")
    amplitude: str = Field("constant", description="Amplitude name (see boundary `displacement`).")


class _Concentrated(Card):
    """What the concentrated loads share: a node set, how the value is spread over it, and an amplitude."""

    nodes: str = Field(description="Node set name.")
    distribution: Literal["per_node", "total"] = Field(
        "per_node", description="per_node: every node gets the value; total: the value is split equally over the set.")
    amplitude: str = Field("smooth", description="Amplitude name (see boundary `displacement`).")


class NodalForce(_Concentrated):
    """Concentrated forces on the nodes of a set [N]."""

    type: Literal["nodal_force"]
    force: Vector = Field(description="Force vector [N].")


class NodalMoment(_Concentrated):
    """Concentrated moments on the shell nodes of a set [N mm] (only its nodes with rotations are loaded), fixed in
    direction (not following the rotation). Only the part normal to each node's current director acts: a shell node
    has no drilling stiffness, so a component about the director could only spin it (it does no work on it)."""

    type: Literal["nodal_moment"]
    moment: Vector = Field(description="Moment vector [N mm] about the global axes.")


for _card in (Gravity, NodalForce, NodalMoment):
    register_card(CardEntry(_card.model_fields["type"].annotation.__args__[0], _card, "effect", "loads"))
