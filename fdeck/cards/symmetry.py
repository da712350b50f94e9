"""Card of a symmetry plane (`symmetry`) for half and quarter models; effect in `fdeck.physics.effects.symmetry`
(it runs on the fixed-dof constraint of `fdeck.physics.effects.boundary`)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


class Symmetry(Card):
    """Mirror symmetry about a plane normal to a global axis through the nodes of a set: the translation along the
    normal is held, and on nodes that carry rotations (shell nodes) the rotations about the two in-plane axes
    (normal x holds x, ry, rz). Every node of the set must lie on one such plane in the reference configuration."""

    type: Literal["symmetry"]
    nodes: str = Field(description="Node set on the symmetry plane (all its nodes share one coordinate along "
                       "`normal`, to 1e-6 of the model size) [-].")
    normal: Literal["x", "y", "z"] = Field(description="Global axis normal to the symmetry plane [-]: x holds x, "
                                           "ry, rz; y holds y, rx, rz; z holds z, rx, ry.")


register_card(CardEntry("symmetry", Symmetry, "effect", "boundary"))
