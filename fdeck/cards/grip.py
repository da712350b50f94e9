"""Card of a spring grip (`spring_grip`): the nodes of a set tied to a movable anchor by linear springs; effect in
`fdeck.physics.effects.grip`."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card

Vector = tuple[float, float, float]
AXIS = {"x": 0, "y": 1, "z": 2}


class SpringGrip(Card):
    """Each node of `nodes` is tied to its own anchor point, at the node's reference position, by a linear spring
    of `stiffness` in each of `dofs`; the anchors move together by u(t) = value * amplitude(t) * direction (a grip
    that pre-tensions the blank). Only the components of u along `dofs` act."""

    type: Literal["spring_grip"]
    nodes: str = Field(description="Node set held by the grip [-].")
    stiffness: float = Field(gt=0.0, description="Spring stiffness per node and per dof [N/mm].")
    dofs: list[Literal["x", "y", "z"]] = Field(default=["x", "y", "z"], min_length=1, description=(
        "Translations the springs act in (x, y, z) [-]."))
    direction: Vector | None = Field(None, description="Direction of the anchors' travel (normalised) [-]; "
                                     "required when `value` is not 0.")
    value: float = Field(0.0, description="Anchor travel at amplitude 1 [mm]; 0 holds the anchors at the nodes' "
                         "reference positions.")
    amplitude: str = Field("smooth", description="Amplitude name; built-ins: constant, ramp, smooth (0 -> 1 over "
                           "the whole run), or a name from `amplitudes` [-].")

    @model_validator(mode="after")
    def _motion(self):
        if len(set(self.dofs)) != len(self.dofs):
            raise ValueError(f"`dofs` repeats a direction: {self.dofs}")
        if self.direction is not None:
            norm = math.sqrt(sum(c * c for c in self.direction))
            if norm == 0.0:
                raise ValueError("`direction` must not be the zero vector")
            if self.value != 0.0 and max(abs(self.direction[AXIS[d]]) for d in self.dofs) <= 1e-12 * norm:
                raise ValueError(f"`direction` {list(self.direction)} has no component along the gripped dofs "
                                 f"{self.dofs}: the anchors' travel would do nothing")
        elif self.value != 0.0:
            raise ValueError("a moving grip (`value` not 0) needs `direction`")
        return self


register_card(CardEntry("spring_grip", SpringGrip, "effect", "boundary"))
