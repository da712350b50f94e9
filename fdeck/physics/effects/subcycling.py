"""Subcycling as a step setting (``steps[i].subcycling``): holds the level plan that ``engine.subcycle`` runs and
reports its cost in the ledger; built only when some step asks for it (the engine then runs ``engine.subcycle.run``
instead of the uniform loop, see ``engine.solver``). The compiler has already split the element groups by update
level (``compile.problem.build_groups`` -> ``engine.subcycle.split_groups``).

History columns (values, not energies): ``subcycling_levels`` the number of step sizes in use in the last major
cycle (1 = uniform), ``subcycling_element_cycles`` the element updates so far, ``subcycling_uniform_element_cycles``
what a uniform step would have cost over the same minor cycles, ``subcycling_step_ratio_max`` the largest ratio of the
step an element's slowest node used to the element's own current stable step (stable below 1).
"""

from __future__ import annotations

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import VALUE, Term
from fdeck.engine.subcycle import static_plan
from fdeck.registry import EffectKind, register_effect


class SubcyclingEffect(Effect):
    deck_settings = ("caps", "top")  # per step, from the deck: not saved (engine.snapshot)
    name = "subcycling"
    subcycles = True  # the engine runs ``engine.subcycle.run`` when a problem has this effect
    terms = (Term("subcycling_levels", VALUE), Term("subcycling_element_cycles", VALUE),
             Term("subcycling_uniform_element_cycles", VALUE), Term("subcycling_step_ratio_max", VALUE))

    def __init__(self, groups: list, n_node: int, caps: list[int]):
        self.caps = caps  # per step: largest level allowed (0: uniform)
        self.top = max(caps)
        # compile-time levels (the groups were split by them); ``engine.subcycle.regroup`` re-derives node, group_level
        # and highest from the current steps at every synchronised time, own_now holds the levels they came from
        self.own, self.node, update, self.highest = static_plan(groups, n_node, self.top)
        self.group_level = [int(u.min()) for u in update]  # one level per group after the split
        self.own_now = [o.copy() for o in self.own]
        self.caps_now = np.full(n_node, self.top, np.int64)  # nodes' caps from contact springs (``node_caps``)
        self.regroups = 0  # synchronised times at which some element changed level
        self.rest_dt = [g.rest_dt(g.rho) for g in groups]
        self.cap = 0
        self.element_cycles = 0
        self.element_cycles_uniform = 0
        self.step_ratio_max = 0.0
        self.over_safety = 0  # group updates where an element's step exceeded dt_safety x its own
        self.level_cycles = np.zeros(self.top + 1, np.int64)  # steps taken by the nodes of each plan level

    def term_values(self) -> tuple[float, ...]:
        return (float(self.cap + 1), float(self.element_cycles), float(self.element_cycles_uniform),
                self.step_ratio_max)

    def refuse(self, effects: list) -> list[tuple[tuple, str]]:
        """Located problems for the built effects the subcycled loop does not run correctly."""
        out = []
        for e in effects:
            if e is self:
                continue
            why = ("acts on rotations" if e.rotational
                   else "integrates its contact springs implicitly (springs: implicit)" if getattr(e, "implicit", False)
                   else f"adds {e.forces} forces" if e.forces not in (None, "external") and not e.subcycling_safe
                   else None)
            if why:
                out.append((getattr(e, "path", ()), f"'{e.name}' {why}, which the subcycled loop "
                            "(steps[].subcycling) does not integrate; remove one of them"))
        return out

    def describe(self, plan) -> str | None:
        sizes = np.bincount(np.concatenate(self.own), minlength=self.top + 1)
        nodes = np.bincount(self.node, minlength=self.top + 1)
        counts = np.zeros(self.top + 1)
        for u, d in zip(self.group_level, self.rest_dt):
            counts[u] += len(d)
        n = counts.sum()
        cost = float((counts / np.exp2(np.arange(self.top + 1))).sum() / n)
        return (f"subcycling (Belytschko-Yen-Mullen nodal partition) up to {self.top + 1} step sizes: elements per "
                f"own level {sizes.tolist()}, nodes per level {nodes.tolist()}, element updates at rest "
                f"{100 * cost:.3g} % of a uniform step's")


def build(cards: list, ctx) -> SubcyclingEffect | None:
    """The effect, or None when no step asks. cards: each step's ``subcycling`` card or None."""
    caps = [0 if c is None else c.levels - 1 for c in cards]
    if not any(caps):
        return None
    deck = ctx.deck
    path = ("steps", next(i for i, c in enumerate(caps) if c), "subcycling")
    problems = []

    def refuse(message: str) -> None:
        problems.append((path, message + " (not supported with subcycling; remove one of them)"))

    if ctx.rotations is not None:
        refuse("the model has shell nodes with rotations")
    for g in ctx.groups:
        if not g.solid:
            refuse(f"group {g.name} holds {g.cell_type} elements; subcycling runs hexahedra only")
    for i, s in enumerate(deck.steps):
        if s.mass_scaling is not None and s.mass_scaling.is_selective:
            refuse(f"steps[{i}] uses selective mass scaling")
        if s.damping is not None:
            refuse(f"steps[{i}] has damping")
        if s.deformation_damping is not None:
            refuse(f"steps[{i}] has deformation damping")
        if s.bulk_viscosity is not None:
            refuse(f"steps[{i}] has bulk viscosity")
    if deck.output.checkpoint is not None:
        refuse("output.checkpoint asks for checkpoints, and the subcycled loop cannot restart from one")
    if problems:
        raise CompileError(problems)
    return SubcyclingEffect(ctx.groups, len(ctx.X), caps)


register_effect(EffectKind("subcycling", build))
