"""Cards of the step settings that the engine runs as effects (``physics.effects.damping``,
``deformation_damping``, ``bulk_viscosity``)."""

from __future__ import annotations

from pydantic import Field

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


class Damping(Card):
    mass_proportional: float = Field(ge=0, description="alpha in f = -alpha m v [1/s]; 2 w damps a mode of "
                                     "angular frequency w critically.")
    added_mass: bool = Field(False, description="Damp the selective mass scaling's added mass too, f = -alpha (M + "
                             "dM) v (physics.effects.damping): the deformation modes that carry it then decay at "
                             "alpha as the rest, rigid motion is dragged as without it; for a dwell that brings a "
                             "blank with added mass to rest, not for a stroke (it also resists the non-rigid "
                             "deformation rates, with the added mass's weight). Needs selective mass scaling in "
                             "the same step.")


class DeformationDamping(Card):
    """Viscous force on each element's nodal velocities relative to its rigid-body motion
    (``physics.effects.deformation_damping``): no drag on rigid sliding or rotation."""

    rate: float = Field(gt=0, description="c in f_a = -c w_a v_def,a [1/s]: the rate at which element-scale "
                        "deformation is damped (a wave of length lambda on elements of size h as by "
                        "mass-proportional damping of c pi^2 (h / lambda)^2).")


class BulkViscosity(Card):
    """Viscous pressure on the volumetric strain rate of solid elements (Abaqus *BULK VISCOSITY defaults)."""

    linear: float = Field(0.06, ge=0, le=1, description="b1: fraction of critical damping of each element's "
                          "fastest mode [-].")
    quadratic: float = Field(1.2, ge=0, le=10, description="b2: quadratic coefficient, compression only [-].")


register_card(CardEntry("damping", Damping, "effect", "step"))
register_card(CardEntry("deformation_damping", DeformationDamping, "effect", "step"))
register_card(CardEntry("bulk_viscosity", BulkViscosity, "effect", "step"))
