"""The material cards users know by name: `interlock` and `3weave` (hexahedral fabrics, MODELS 2-3) and `sm` and
`ts` (woven shells in LS-DYNA's shell-membrane and thick-shell vocabulary, MODELS 5).

Each is exactly a general card with a preset: the same fields, every one overridable in the deck, the same packed
parameters and kernels (``CardEntry.kind``). `sm` and `ts` also imply their section formulation: a section of such
a material that names no formulation gets it (and the section preset of the same name when it gives neither a
preset nor a thickness); a section that names another one is a located error (``deck.model``).
"""

from __future__ import annotations

from typing import ClassVar, Literal

from fdeck.cards.fabric_hyper import FabricHyper
from fdeck.cards.fabric_membrane import FabricMembrane
from fdeck.registry import CardEntry, register_card


def _named(base, name: str, preset: str, doc: str):
    """A card class that is ``base`` with ``type: name`` and ``preset`` used when the deck names none."""
    namespace = {"__module__": __name__, "__qualname__": name, "__doc__": doc, "default_preset": preset,
                 "__annotations__": {"type": Literal[name], "default_preset": ClassVar[str]}}
    return type(base)(f"Named_{name}", (base,), namespace)


Interlock = _named(FabricHyper, "interlock", "interlock", "Thick carbon layer-to-layer interlock on hexahedra: "
                   "`fabric_hyper` with preset `interlock` (representative).")
ThreeWeave = _named(FabricHyper, "3weave", "3weave", "Non-crimp 3D orthogonal E-glass weave on hexahedra: "
                    "`fabric_hyper` with preset `3weave` (published).")
ShellMembrane = _named(FabricMembrane, "sm", "t300_3k", "Woven T300-3K on `sm` shells (shell-membrane hybrid): "
                       "`fabric_membrane` with preset `t300_3k`.")
ThickShell = _named(FabricMembrane, "ts", "t300_3k_ts", "Woven T300-3K on `ts` thick shells (Reissner-Mindlin): "
                    "`fabric_membrane` with preset `t300_3k_ts`.")


for _card, _kind, _formulation, _aliases in (
        (Interlock, "fabric_hyper", "", ("3d_interlock", "layer_to_layer")),
        (ThreeWeave, "fabric_hyper", "", ("three_weave", "3_weave", "3d_weave")),
        (ShellMembrane, "fabric_membrane", "sm", ("shell_membrane", "s-m", "shellmembrane", "mat249")),
        (ThickShell, "fabric_membrane", "ts", ("thick_shell", "t-s", "thickshell"))):
    register_card(CardEntry(_card.model_fields["type"].annotation.__args__[0], _card, "material",
                            description=_card.__doc__, kind=_kind, preset=_card.default_preset,
                            formulation=_formulation, section_preset="t300_3k" if _formulation else "",
                            aliases=_aliases))
