"""Section cards of the 4-node shells and membranes (`sm`, `ts`, `membrane`) and their presets; elements in
`fdeck.physics.elements.shell4`. No numpy or numba here."""

from __future__ import annotations

from importlib import resources
from typing import Literal

from pydantic import Field, model_validator

from fdeck.cards import presets
from fdeck.deck.section import SectionBase
from fdeck.registry import CardEntry, register_card


PRESET_DIR = resources.files(__package__).joinpath("presets")


def load_section_preset(kind: str, name: str) -> dict:
    """Fields of section preset ``name`` of formulation ``kind`` (presets/<kind>/<name>.yaml)."""
    allowed = {"sm": SmSection, "ts": TsSection, "membrane": MembraneSection}[kind].model_fields
    return presets.load(PRESET_DIR.joinpath(kind), name, allowed, f"{kind} section")


class _ShellSection(SectionBase):
    preset: str | None = Field(None, description="Name of a section preset in fdeck/cards/presets/<kind>.")
    thickness: float | None = Field(None, gt=0.0, description="Shell thickness h [mm].")

    @model_validator(mode="before")
    @classmethod
    def _merge_preset(cls, data):
        if not isinstance(data, dict) or data.get("preset") is None:
            return data
        kind = data.get("formulation", "")
        if not PRESET_DIR.joinpath(kind).is_dir():
            raise ValueError(f"formulation {kind!r} has no presets")
        return presets.merged(data, lambda name: load_section_preset(kind, name))

    @model_validator(mode="after")
    def _complete(self):
        missing = [k for k, f in type(self).model_fields.items() if getattr(self, k) is None and k != "preset"]
        if missing:
            raise ValueError(f"{self.formulation}: {', '.join(missing)} not defined by the deck or a preset")
        return self


class _DirectorSection(_ShellSection):
    normal_stiffness: float = Field(0.0, ge=0.0, description=(
        "k_n [N/mm]: ties each nodal director to the nodal normal of the mid-surface (area-weighted normal of the "
        "section's elements at the node) by an energy k_n A_a (1 - d_a . n_a) per node (A_a its tributary area), "
        "about 1/2 k_n A_a theta^2: a transverse shear of the director against the surface normal instead of "
        "against the element edges (MITC4), which lets an element-scale zig-zag of the mid-surface turn the "
        "directors without limit. 0 (default) switches it off."))


class MembraneSection(_ShellSection):
    """Membrane: the fabric in-plane law at the mid-surface, no bending, no rotational dofs."""

    formulation: Literal["membrane"]


class SmSection(_DirectorSection):
    """Shell-membrane hybrid of [J]: fabric law at the mid-surface plus decoupled orthotropic elastic bending
    (D11 = D22 = EI, D66 = GI per unit width), Kirchhoff-Love in effect (stiff transverse shear)."""

    formulation: Literal["sm"]
    bending_stiffness: float | None = Field(None, ge=0.0, description=(
        "EI per unit width along the yarns [N mm] (D11 = D22): moment per width over curvature."))
    twisting_stiffness: float | None = Field(None, ge=0.0, description=(
        "GI per unit width [N mm] (D66, twisting term). A 45-deg strip bends with 1 / (1/(2 EI) + 1/(4 GI)), so "
        "GI = 1 / (4 (1/EI_45 - 1/(2 EI))) from a 45-deg bending test."))
    transverse_shear_penalty: float = Field(100.0, gt=0.0, description=(
        "alpha in the transverse shear stiffness k_s = min(alpha 12 D_max / A_e, M0 h / 4) [N/mm] (A_e element "
        "area, M0 rest wave modulus of the law): the shear share of a bending deflection over a span l is "
        "A_e / (alpha l^2)."))


class TsSection(_DirectorSection):
    """Thick shell of [J] (Reissner-Mindlin): the fabric law at `points` levels through the thickness plus
    transverse shear G13 = G23."""

    formulation: Literal["ts"]
    points: int | None = Field(None, ge=2, le=9, description="Integration points through the thickness.")
    integration: Literal["gauss", "lobatto"] = Field("gauss", description=(
        "Through-thickness rule: gauss (points inside) or lobatto (one on each face)."))
    transverse_shear_modulus: float | None = Field(None, gt=0.0, description="G13 = G23 [MPa].")
    shear_correction: float | None = Field(5.0 / 6.0, gt=0.0, le=1.0, description=(
        "kappa in k_s = kappa G13 h (5/6: homogeneous rectangular section; alpha = 1/kappa in MODELS 5)."))


for _card, _doc in (
        (SmSection, "shell-membrane hybrid: fabric law at the mid-surface + decoupled orthotropic bending (EI, GI), "
                    "Kirchhoff-Love in effect; 4-node MITC4 shell, 2x2 points"),
        (TsSection, "thick shell: fabric law at N levels through the thickness + transverse shear G13; 4-node MITC4 "
                    "Reissner-Mindlin shell, 2x2 points"),
        (MembraneSection, "fabric law at the mid-surface only; 4-node membrane, 2x2 points")):
    register_card(CardEntry(_card.model_fields["formulation"].annotation.__args__[0], _card, "formulation",
                            description=_doc, cell_types=("quad", "triangle"), plane_stress=True))
