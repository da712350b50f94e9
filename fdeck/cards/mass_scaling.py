"""Card of a step's mass scaling (``steps[i].mass_scaling``): conventional (density) or selective; the selective
kind runs in the engine as an effect (``physics.effects.selective_mass``), built only when a step asks for it."""

from __future__ import annotations

from pydantic import Field, model_validator

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


class MassScaling(Card):
    """Mass scaling: a fixed density factor, or per-element added mass to reach a target time step."""

    factor: float | None = Field(None, ge=1.0, description="Density multiplier (dt grows by sqrt(factor)).")
    target_dt: float | None = Field(None, gt=0, description="Target stable time step [s]; mass is added to "
                                    "elements whose rest stable step is smaller, and the added mass is reported.")
    selective: bool = Field(False, description="Selective mass scaling (hexahedra): the mass is added only to the "
                            "modes that deform an element, not to its translation (Olovsson, Simonsson & Unosson "
                            "2005), so total mass, momentum and the slow bending modes stay as they are; the "
                            "non-diagonal mass is solved each cycle by conjugate gradients.")
    cg_tolerance: float = Field(1e-4, gt=0, lt=1, description="Selective scaling: the conjugate-gradient solve "
                                "stops when the residual's norm (weighted by the inverse diagonal) falls below "
                                "this fraction of the right-hand side's [-].")
    cg_max_iterations: int = Field(200, ge=1, description="Selective scaling: iteration cap of the solve per cycle; "
                                   "a cycle that reaches it is counted and reported, not stopped.")

    @model_validator(mode="after")
    def _one_of(self):
        if (self.factor is None) == (self.target_dt is None):
            raise ValueError("give exactly one of `factor` or `target_dt`")
        return self


register_card(CardEntry("mass_scaling", MassScaling, "effect", "step"))
