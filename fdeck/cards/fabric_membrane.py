"""Card of the woven-fabric in-plane law for shells and membranes (`fabric_membrane`, MAT 249 style): load curves,
presets. Kernels and the packed layout in `fdeck.physics.materials.fabric_membrane`; no numpy or numba here."""

from __future__ import annotations

from importlib import resources
from typing import Annotated, ClassVar, Literal

from pydantic import Field, FiniteFloat, model_validator

from fdeck.cards import presets
from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


MAX_POINTS = 16
"""Largest number of points of one load curve (fixes the parameter block size)."""


PRESET_DIR = resources.files(__package__).joinpath("presets", "fabric_membrane")
"""Folder of this card's preset files (a module attribute so tests can point it elsewhere)."""


Point = tuple[FiniteFloat, FiniteFloat]


class FibreCurves(Card):
    """Stress-strain load curves of one fibre family: second Piola-Kirchhoff stress [MPa] against Green-Lagrange
    strain [-], piecewise linear, continued with the last slope beyond the last point."""

    tension: list[Point] = Field(min_length=2, max_length=MAX_POINTS, description=(
        "Points (E >= 0 [-], S [MPa]) from (0, 0), E strictly increasing; the first slope must be > 0."))
    compression: list[Point] = Field(min_length=2, max_length=MAX_POINTS, description=(
        "Points (E <= 0 [-], S [MPa]) from (0, 0), E strictly decreasing (S usually <= 0)."))

    @model_validator(mode="after")
    def _check(self):
        for name, pts, sign in (("tension", self.tension, 1.0), ("compression", self.compression, -1.0)):
            if tuple(pts[0]) != (0.0, 0.0):
                raise ValueError(f"{name}: the first point must be (0, 0) (stress-free at rest)")
            e = [sign * p[0] for p in pts]
            if any(b <= a for a, b in zip(e, e[1:])):
                raise ValueError(f"{name}: strains must {'increase' if sign > 0 else 'decrease'} strictly from 0")
        if self.tension[1][1] <= 0.0:
            raise ValueError("tension: the first segment's slope must be > 0 (it sets the stable step at rest)")
        return self


class ShearCurve(Card):
    """In-plane shear: tau = dPhi/dgamma [MPa] (per reference volume) against the shear angle between the fibres."""

    curve: list[Point] = Field(min_length=2, max_length=MAX_POINTS, description=(
        "Points (gamma [deg], tau [MPa]) from (0, 0), gamma strictly increasing; odd in gamma."))
    locking_angle: float = Field(gt=0.0, lt=90.0, description=(
        "Locking angle [deg]; beyond it tau grows with `locking_modulus` from its value at the locking angle."))
    locking_modulus: float = Field(ge=0.0, description="Slope dtau/dgamma beyond the locking angle [MPa/rad].")

    @model_validator(mode="after")
    def _check(self):
        if tuple(self.curve[0]) != (0.0, 0.0):
            raise ValueError("curve: the first point must be (0, 0)")
        g = [p[0] for p in self.curve]
        if any(b <= a for a, b in zip(g, g[1:])):
            raise ValueError("curve: angles must increase strictly")
        return self


def available_presets() -> list[str]:
    return presets.names(PRESET_DIR)


def load_preset(name: str) -> dict:
    return presets.load(PRESET_DIR, name, {"density", "warp", "weft", "shear"}, "fabric_membrane")


class FabricMembrane(presets.PresetMaterial):
    """Fabric in-plane law (MAT 249 style, hyperelastic) for shell and membrane sections: warp and weft load curves
    (tension and compression apart), shear stress against shear angle with a locking angle and a post-locking
    modulus. Plane stress: no through-thickness energy. ``preset: t300_3k`` (and ``t300_3k_ts`` for the thick
    shell) gives REPRESENTATIVE curves of a plain-weave carbon T300-3K; deck keys replace the preset's."""

    type: Literal["fabric_membrane"]
    preset_loader: ClassVar = staticmethod(lambda name: load_preset(name))
    required: ClassVar = ("density", "warp", "weft", "shear")
    density: Annotated[float, Field(gt=0.0)] | None = Field(
        None, description="Mass density [t/mm^3]; taken from the preset when omitted.")
    preset: str | None = Field(None, description="Name of a file in fdeck/cards/presets/fabric_membrane.")
    warp: FibreCurves | None = Field(None, description="Load curves of the warp family (frame row 0).")
    weft: FibreCurves | None = Field(None, description="Load curves of the weft family (frame row 1).")
    shear: ShearCurve | None = Field(None, description="In-plane shear curve, locking angle and modulus.")


register_card(CardEntry("fabric_membrane", FabricMembrane, "material"))
