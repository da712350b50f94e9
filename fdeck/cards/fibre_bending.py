"""Card of the local fibre bending stiffness of hexahedral sections (`fibre_bending`, [B] cure 2); the effect, its
packed law and kernels in `fdeck.physics.effects.fibre_bending`."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, FiniteFloat, model_validator

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card


MAX_TABLE = 16
"""Largest number of (chi, M) points of a tabulated law."""


class BendingLaw(Card):
    """Moment per unit width M(chi) of one fibre family (see ``FibreBending.thickness`` for what M is per).

    Give D1 (and optionally D2): M = D1 chi + D2 chi^3; or a table of (chi, M) points starting at (0, 0),
    interpolated linearly and extended with the last slope. M is odd in chi (the same law in both bending senses).
    """

    D1: FiniteFloat | None = Field(None, ge=0.0, description="Linear bending rigidity per unit width [N mm] "
                                   "(M [N mm/mm] = D1 chi + D2 chi^3, chi [1/mm]).")
    D2: FiniteFloat = Field(0.0, ge=0.0, description="Cubic coefficient of the moment law [N mm^3].")
    table: list[tuple[FiniteFloat, FiniteFloat]] | None = Field(
        None, min_length=2, max_length=MAX_TABLE,
        description="Instead of D1, D2: [[chi [1/mm], M [N mm/mm]], ...] from [0, 0], chi increasing, M "
                    "non-decreasing; linear between points, last slope beyond the last point.")

    @model_validator(mode="after")
    def _one_law(self):
        if (self.D1 is None) == (self.table is None):
            raise ValueError("give either `D1` (and optionally `D2`) or `table`")
        if self.table is not None:
            if self.D2 != 0.0:
                raise ValueError("`D2` belongs to the D1, D2 law; a `table` law takes no coefficients")
            _check_table(self.table)
        elif self.D1 + self.D2 <= 0.0:
            raise ValueError("D1 and D2 are both zero: this family would not bend (leave it out instead)")
        return self


def _check_table(table) -> None:
    chi = [p[0] for p in table]
    m = [p[1] for p in table]
    if chi[0] != 0.0 or m[0] != 0.0:
        raise ValueError(f"the first table point must be [0, 0], got {list(table[0])}")
    if any(b <= a for a, b in zip(chi, chi[1:])):
        raise ValueError("curvatures in `table` must increase strictly")
    if any(b < a for a, b in zip(m, m[1:])):
        raise ValueError("moments in `table` must not decrease (a falling moment has no stable bending energy)")
    if m[-1] <= 0.0:
        raise ValueError("every moment in `table` is zero: this family would not bend")


class InPlaneLaws(Card):
    """Moment laws of the fibres bent in the fabric's plane (about the section normal): the second-gradient energy
    that gives a jump of shear angle across a fibre line a width (Ferretti, Madeo, dell'Isola and Boisse 2014;
    Barbagallo et al. 2017). M per unit width of the specimen of thickness T, as for out-of-plane bending."""

    warp: BendingLaw | None = Field(None, description="In-plane moment law of warp fibres (their curvature in the "
                                    "fabric plane); leave out if warp does not bend in plane.")
    weft: BendingLaw | None = Field(None, description="In-plane moment law of weft fibres; leave out if weft does "
                                    "not bend in plane.")

    @model_validator(mode="after")
    def _some_family(self):
        if self.warp is None and self.weft is None:
            raise ValueError("give an in-plane moment law for `warp`, `weft` or both")
        return self


class FibreBendingLaws(Card):
    """The moment laws of a fabric's fibre families and the specimen thickness they are per: the body of a
    `fibre_bending` section effect, and the `fibre_bending` field of a `fabric_hyper` material (a fabric's own
    bending, e.g. from a preset identified on cantilever tests, applied on every section of that material)."""

    thickness: FiniteFloat = Field(gt=0.0, description="Thickness T of the fabric specimen whose moment per unit "
                                   "width M(chi) the laws give [mm]; the energy density is int M dchi / T, so a "
                                   "sheet of thickness T bent to chi stores int M dchi per unit area.")
    warp: BendingLaw | None = Field(None, description="Moment law of warp fibres (curvature along warp); "
                                    "leave out if warp does not bend.")
    weft: BendingLaw | None = Field(None, description="Moment law of weft fibres (curvature along weft); "
                                    "leave out if weft does not bend.")
    in_plane: InPlaneLaws | None = Field(None, description="Moment laws of the fibres bent in the fabric's plane "
                                         "(in-plane curvature, hinges between the same neighbours); leave out for "
                                         "out-of-plane bending only.")

    @model_validator(mode="after")
    def _some_family(self):
        if self.warp is None and self.weft is None and self.in_plane is None:
            raise ValueError("give a moment law for `warp`, `weft`, `in_plane` or several")
        return self


class FibreBending(FibreBendingLaws):
    """Local fibre bending stiffness ([B] cure 2): a moment-curvature law per fibre family, on the section's
    hexahedra, curvature from neighbouring elements (fibre-aligned meshes). Energy in history column
    `bending_energy`; its stiffness enters the stable time step."""

    type: Literal["fibre_bending"]


register_card(CardEntry("fibre_bending", FibreBending, "effect", "section"))
