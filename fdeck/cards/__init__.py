"""Deck cards of the plug-ins: pydantic models only (no numpy, no numba), each module registering its cards with
``fdeck.registry.register_card``. Imported by ``fdeck.deck.model``; the kernels live in ``fdeck.physics``."""

from fdeck.cards import boundary, contact, elastic, fabric_hyper, fabric_membrane, fibre_bending, loads  # noqa: F401
from fdeck.cards import measures, named, shell_sections, solid_sections, steps  # noqa: F401
from fdeck.cards import grip, symmetry  # noqa: F401
from fdeck.cards import mass_scaling  # noqa: F401
from fdeck.cards import subcycling  # noqa: F401
