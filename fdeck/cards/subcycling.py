"""Card of a step's subcycling (``steps[i].subcycling``): node steps that are powers of two of the smallest, run by
``engine.subcycle`` (and reported by the effect ``physics.effects.subcycling``), built only when a step asks."""

from __future__ import annotations

from pydantic import Field

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


class Subcycling(Card):
    """Multi-time-step integration (Belytschko, Yen & Mullen 1979 nodal partition): elements are binned by their own
    stable step into levels k (step 2^k x the smallest), each node runs at the smallest level of its elements, and
    only the elements whose nodes are due are updated; history rows and frames are taken at synchronised times."""

    levels: int = Field(4, ge=2, le=8, description="Number of step sizes: nodes run at dt, 2 dt, ..., "
                        "2^(levels-1) dt, dt the smallest element step times dt_safety [-].")
    block_elements: int = Field(256, ge=1, description="Largest number of elements in one block: each section is "
                                "split into spatially compact blocks, each updated at the rate of its fastest "
                                "element, so a local stiffening slows only its own blocks; smaller blocks follow it "
                                "more closely for a few microseconds of call overhead per block and update [-].")


register_card(CardEntry("subcycling", Subcycling, "effect", "step"))
