"""Registries of material cards, element formulations and effects.

A plug-in has two sides, each registered with one call: its card (``fdeck/cards/``, no numpy or numba; imported by
``fdeck.cards``) and its kernels (``fdeck/physics/``; imported by ``fdeck.physics``). The deck builds its
discriminated unions from the card tables, the compiler looks kinds up in the kernel tables: nowhere else does code
branch on a card's ``type``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable


@dataclass(frozen=True)
class MaterialKind:
    """A constitutive law.

    pack(card) -> float64 array (n_param,): canonical parameters, the same for every element of a section.
    evaluate(F, frame, params, state, P, psi, modulus): numba kernel over elements, shapes
        F (n_el, n_qp, 3, 3) deformation gradient; frame (n_el, 3, 3) rows = warp, weft, thickness unit vectors
        in the reference configuration; params (n_el, n_param); state (n_el, n_qp, n_state) updated in place;
        outputs P (n_el, n_qp, 3, 3) first Piola-Kirchhoff stress [MPa], psi (n_el, n_qp) energy density per
        reference volume [MPa = mJ/mm3], modulus (n_el, n_qp, 3) current wave-modulus bounds [MPa] along the
        three frame directions, for the stable step: the reference acoustic tensor Q(N) = N.(dP/dF).N of every unit
        N is at most sum_i modulus_i (f_i . N)^2 (isotropic laws give one value thrice; an anisotropic law lets an
        element pair its stiff direction with the element's own length along it, see ``hex8.element_dt``).
    point(F, frame, params, state, P) -> (psi, m1, m2, m3): the same at one point (3x3 arrays), for tests.
    n_state: history variables per integration point (0 for hyperelastic laws).
    diagnostics: names of the per-point output fields returned by ``diagnose``.
    diagnose(F, frame, params) -> float64 array (len(diagnostics),) at one point, or None.
    plane_stress: the stress has no component along the frame's third row (S f3 = 0) and the energy does not
        depend on F f3, so shells and membranes may carry the law with F f3 = unit normal (no thickness condensation).
    """

    name: str
    pack: Callable[[Any], Any]
    evaluate: Callable
    point: Callable
    n_state: int = 0
    diagnostics: tuple[str, ...] = ()
    diagnose: Callable | None = None
    plane_stress: bool = False


@dataclass(frozen=True)
class EffectKind:
    """A boundary condition, load, damping, tool contact or section-level add-on (its card: ``CardEntry``).

    build(card, ctx) -> engine.effect.Effect, called by the compiler only for effects a deck names, with ``ctx`` a
        ``compile.problem.Context`` (mesh, groups, rotations, surfaces, sets, amplitudes). The card's section says
        how: 'boundary' or 'loads' (one per card of that deck list), 'section' (an add-on of a section, built once
        per group of that section, ``ctx.group``) or 'step' (a setting of every step, ``steps[i].<name>``: build gets
        the list of the steps' cards, None where a step has none, and returns an Effect or None when no step needs
        it; the effect learns the current step through ``begin_step``).
    """

    name: str
    build: Callable


@dataclass(frozen=True)
class FormulationKind:
    """An element formulation (a way to turn nodal positions into forces for one element shape); its section card,
    description and accepted cell types are the ``CardEntry`` of the same name.

    build(name, section card, X, conn, ids, material kind, params, orientation, rho, cell_type) -> engine group
    (``engine.group.ElementGroup``), with orientation a ``fdeck.compile.orientation.ElementOrientation``.
    """

    name: str
    build: Callable
    nodes_per_element: int = 8


@dataclass(frozen=True)
class MeasureKind:
    """A quantity a deck asks to be recorded (history column(s) and final value in summary.json).

    build(card, ctx) -> object with ``columns`` (list of names) and ``evaluate(x, v) -> list[float]``.
    """

    name: str
    build: Callable


@dataclass(frozen=True)
class CardEntry:
    """The deck side of a plug-in: its pydantic card, registered by a module of ``fdeck.cards`` that imports neither
    numpy nor numba, so that reading and validating a deck never loads a kernel. The kernel side registers a kind of
    the same name (``MaterialKind``, ``EffectKind``, ``FormulationKind``, ``MeasureKind``).

    table: "material", "effect", "measure" or "formulation".
    section: for effects, the deck list the card goes in ('boundary', 'loads', 'section' or 'step').
    card: the pydantic model; for formulations the section card, None for the solid section of ``deck.model``.
    description: one line for messages and the schema (formulations).
    cell_types: mesh cell types (meshio names) a formulation accepts.
    plane_stress: the formulation carries only plane-stress laws (``MaterialKind.plane_stress``).
    kind: the kernel side this card runs on when it is a named preset of a general card (``3weave`` runs on
        ``fabric_hyper``); empty for a general card (its own name).
    preset: the preset a named card expands to.
    formulation: the section formulation a named material card implies (``sm``, ``ts``), with ``section_preset``
        the section preset it fills in when a section gives neither a preset nor a thickness.
    aliases: other spellings that did-you-mean maps to this card (compared without case, spaces, - and _).
    """

    name: str
    card: type | None
    table: str
    section: str = ""
    description: str = ""
    cell_types: tuple[str, ...] = ("hexahedron",)
    plane_stress: bool = False
    kind: str = ""
    preset: str = ""
    formulation: str = ""
    section_preset: str = ""
    aliases: tuple[str, ...] = ()

    @property
    def runs_on(self) -> str:
        """Name of the kernel-side kind."""
        return self.kind or self.name


CARDS: dict[str, dict[str, CardEntry]] = {"material": {}, "effect": {}, "measure": {}, "formulation": {}}
MATERIALS: dict[str, MaterialKind] = {}
MEASURES: dict[str, MeasureKind] = {}
EFFECTS: dict[str, EffectKind] = {}
FORMULATIONS: dict[str, FormulationKind] = {}



def _add(table: dict, kind) -> None:
    if kind.name in table:
        raise ValueError(f"{kind.name!r} is registered twice")
    table[kind.name] = kind


def register_material(kind: MaterialKind) -> None:
    _add(MATERIALS, kind)


def register_effect(kind: EffectKind) -> None:
    _add(EFFECTS, kind)


def register_formulation(kind: FormulationKind) -> None:
    _add(FORMULATIONS, kind)


def register_measure(kind: MeasureKind) -> None:
    _add(MEASURES, kind)


def register_card(entry: CardEntry) -> None:
    _add(CARDS[entry.table], entry)


def cards(table: str, section: str | None = None) -> dict[str, CardEntry]:
    """The registered cards of a table (and effect section), importing the card modules on first use."""
    import fdeck.cards  # noqa: F401  (each card module registers itself)

    return {k: v for k, v in CARDS[table].items() if section is None or v.section == section}


def load_plugins() -> None:
    """Import every plug-in module (each registers its kernel side)."""
    import fdeck.physics  # noqa: F401
