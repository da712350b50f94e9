"""What every section card has (element set, material, fibre orientation); formulation modules extend it.

Kept apart from ``fdeck.deck.model`` so that plug-in modules (imported while the model is being built) can derive
their own section cards from it.
"""

from __future__ import annotations

from pydantic import Field

from fdeck.deck.base import Card

Vector = tuple[float, float, float]


class Orientation(Card):
    """Fibre frame of a section: warp lies in the plane normal to `normal`, at `warp_angle` (right-handed about
    `normal`) from the projection of `reference` on that plane; weft = normal x warp (at +90 deg); thickness =
    normal. A +-45 deg blank is `warp_angle: 45`. For shells and membranes the plane is each element's own tangent
    plane: `reference` is projected on it and `warp_angle` turns about the element normal taken on the side of
    `normal`."""

    warp_angle: float = Field(0.0, description="Angle of the warp from the reference direction [deg].")
    normal: Vector = Field((0.0, 0.0, 1.0), description="Sheet normal (thickness direction).")
    reference: Vector = Field((1.0, 0.0, 0.0), description="Direction of warp at angle 0 (projected).")
    field: str | None = Field(None, description="Cell field of the mesh file varying the orientation per element: "
                              "1 component = warp angle [deg] added to `warp_angle`, 3 components = `reference` "
                              "per element.")


class SectionBase(Card):
    """Assigns a material and an element formulation to an element set."""

    elements: str = Field("all", description="Element set name.")
    material: str = Field(description="Name of a card in `materials`.")
    orientation: Orientation = Field(default_factory=Orientation)
