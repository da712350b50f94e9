"""Cards of the isotropic verification laws (`linear_elastic`, `neo_hookean`); kernels in `fdeck.physics.materials`."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from fdeck.deck.base import MaterialCard
from fdeck.registry import CardEntry, register_card


class Isotropic(MaterialCard):
    """Fields of an isotropic law given by its (small-strain) Young's modulus and Poisson ratio."""

    youngs_modulus: float = Field(gt=0.0, description="Young's modulus E [MPa] (small-strain for hyperelastic laws).")
    poisson_ratio: float = Field(gt=-1.0, lt=0.5, description="Poisson ratio nu, -1 < nu < 0.5.")


class LinearElastic(Isotropic):
    """Isotropic linear elastic (Saint Venant-Kirchhoff at finite strain)."""

    type: Literal["linear_elastic"]


class NeoHookean(Isotropic):
    """Compressible neo-Hookean hyperelastic solid."""

    type: Literal["neo_hookean"]


register_card(CardEntry("linear_elastic", LinearElastic, "material"))
register_card(CardEntry("neo_hookean", NeoHookean, "material"))
