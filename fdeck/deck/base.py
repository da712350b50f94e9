"""Base classes every card derives from: unknown keys are errors, cards are frozen after validation."""

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field


class Card(BaseModel):
    """A block of the deck. Unknown keys are rejected (with a did-you-mean, see ``deck.errors``); NaN and
    infinities are rejected in every number (no deck quantity is meant to be one, and they reach the compiler
    as crashes or silent NaN fields)."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True, allow_inf_nan=False)


Density = Annotated[float, Field(gt=0.0, description="Mass density [t/mm^3 in mm-t-s units].")]


class MaterialCard(Card):
    """Base of every material card."""

    density: Density

    def section_effects(self) -> list:
        """(field name, section effect card) of the add-ons this material carries, built on every section of it
        as if the section listed them (e.g. a fabric's own fibre bending from its preset); none by default."""
        return []
