"""Cards of the recorded quantities (`output.measures`); evaluators in `fdeck.physics.measures`."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


class ElementAverage(Card):
    """Average of a cell output field (e.g. shear_angle, warp_strain, J) over the elements of a set."""

    type: Literal["element_average"]
    name: str = Field(description="Column name in history.csv and key in summary.json.")
    elements: str = Field(description="Element set name.")
    field: str = Field(description="Name of a cell output field of the set's sections (see the materials' docs).")
    reduce: Literal["mean", "min", "max"] = "mean"


class NodeDisplacement(Card):
    """A component of the displacement [mm] of a node set, reduced to one number."""

    type: Literal["node_displacement"]
    name: str = Field(description="Column name in history.csv and key in summary.json.")
    nodes: str = Field(description="Node set name.")
    component: Literal["x", "y", "z", "magnitude"] = "z"
    reduce: Literal["mean", "min", "max"] = "mean"


class PinJointedShear(Card):
    """Kinematic (pin-jointed net) central shear angle [deg] of a bias-extension sample."""

    type: Literal["pin_jointed_shear"]
    name: str = Field(description="Column name in history.csv and key in summary.json.")
    clamp: str = Field(description="Node set of the moving clamp.")
    axis: Literal["x", "y", "z"] = Field("y", description="Pull direction.")
    width: float = Field(gt=0, description="Sample width W [mm].")
    free_length: float = Field(gt=0, description="Free length H between the clamps [mm] (H >= 2 W).")

    @model_validator(mode="after")
    def _long_enough(self):
        if self.free_length < 2 * self.width:
            raise ValueError("a bias-extension sample needs free_length >= 2 width")
        return self


class SurfaceWaviness(Card):
    """Largest short-wave deviation [mm] of a surface from a locally quadratic shape."""

    type: Literal["surface_waviness"]
    name: str = Field(description="Column name in history.csv and key in summary.json.")
    nodes: str = Field(description="Node set of the surface (e.g. zmax of a block).")
    along: Literal["x", "y", "z"] = Field("x", description="Direction of the lines (e.g. the beam length).")
    height: Literal["x", "y", "z"] = Field("z", description="Component measured (e.g. the deflection direction).")


class DrawIn(Card):
    """Draw-in [mm] of a blank edge: mean and largest inward displacement of a node set in the plane normal to the
    punch axis (columns `<name>_mean`, `<name>_max`)."""

    type: Literal["draw_in"]
    name: str = Field(description="Column prefix in history.csv and summary.json.")
    nodes: str = Field(description="Node set of the blank edge.")
    axis: Literal["x", "y", "z"] = Field("z", description="Punch axis; displacement along it does not count.")
    centre: tuple[float, float, float] | None = Field(
        None, description="Point [mm] the inward directions aim at (default: centroid of the mesh's reference "
        "nodes).")


class Wrinkles(Card):
    """Wrinkle indicator [mm]: per node of a surface, |height - local quadric fit| over the nodes within `radius`;
    largest value and 99th percentile per region (columns `<name>_max`, `<name>_p99`, `<name>_<region>_...`),
    frame point field `wrinkle`."""

    type: Literal["wrinkles"]
    name: str = Field(description="Column prefix in history.csv and summary.json.")
    nodes: str = Field(description="Node set of the surface (shell nodes, or the top face of a hexahedral blank).")
    radius: float = Field(gt=0, description="Patch radius R [mm], about a wrinkle wavelength (wrinkles shorter "
                          "than 2R score their amplitude; at least 1.5 element sizes).")
    regions: list[str] = Field(default_factory=list, description="Node or element sets reported separately.")

    @model_validator(mode="after")
    def _unique_regions(self):
        dup = sorted({r for r in self.regions if self.regions.count(r) > 1})
        if dup:
            raise ValueError(f"regions repeated: {dup}")
        return self


for _card in (DrawIn, Wrinkles):
    register_card(CardEntry(_card.model_fields["type"].annotation.__args__[0], _card, "measure"))

for _card in (ElementAverage, NodeDisplacement, PinJointedShear, SurfaceWaviness):
    register_card(CardEntry(_card.model_fields["type"].annotation.__args__[0], _card, "measure"))
