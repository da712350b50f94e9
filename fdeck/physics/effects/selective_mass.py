"""Selective mass scaling as a step setting (``steps[i].mass_scaling.selective``): the engine's added-mass solve
(``engine.selective_mass``) wrapped as an effect, built only when some step asks for it.

The step plan (``compile.problem.plan_steps``) gives each element its factor beta_e (from ``target_dt`` or
``factor``, the same element steps as conventional mass scaling); this effect holds the solver state (saved in
checkpoints with the effect), the prescribed-dof mask of the step, and reports: the added kinetic energy
1/2 v^T dM v (a share of the engine's ``kinetic_energy``, shown, not summed again), the mean and largest
conjugate-gradient iterations per cycle so far, and the cycles that reached the iteration cap.
"""

from __future__ import annotations

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.engine.ledger import VALUE, Term
from fdeck.engine.selective_mass import SelectiveMass
from fdeck.registry import EffectKind, register_effect


class SelectiveMassEffect(Effect):
    name = "selective_mass"
    solves_mass = True  # the engine hands it the accelerations of every cycle (``engine.solver``)
    terms = (Term("added_kinetic_energy", VALUE), Term("cg_iterations_mean", VALUE),
             Term("cg_iterations_max", VALUE), Term("cg_capped_cycles", VALUE))

    def __init__(self, groups: list, X: np.ndarray, selective: list[bool]):
        self.solver = SelectiveMass([g.conn for g in groups], X)
        self.groups = groups
        self.selective = selective
        self.plan = None
        self.ke = 0.0

    def begin_step(self, index, plan):
        self.plan = plan

    @property
    def active(self) -> bool:
        return self.plan is not None and self.plan.selective is not None

    def prepare(self, constraints: list, x: np.ndarray) -> None:
        """Set the step up (called by the engine after ``begin_step``): the prescribed dofs are those the
        constraints write (found by letting them write into NaNs; translational constraints only, as selective
        scaling is refused with rotations)."""
        probe = np.full(x.shape, np.nan)
        for c in constraints:
            c.constrain(0.0, 1.0, x.copy(), probe)
        free = np.isnan(probe).astype(float)
        # element masses of the translational (base) density rho / (1 + beta): physical, or uniformly scaled
        base = [g.mass(r / (1.0 + b)).sum(axis=1) for g, r, b in zip(self.groups, self.plan.rho, self.plan.selective)]
        self.solver.set_step(self.plan.selective, base, self.plan.mass, free, self.plan.cg)

    def term_values(self) -> tuple[float, ...]:
        s = self.solver
        return (self.ke, s.iterations / max(s.cycles, 1), float(s.max_iterations), float(s.capped))

    def describe(self, plan) -> str | None:
        steps = [i for i, on in enumerate(self.selective) if on]
        if plan.selective is None:
            return f"selective mass scaling in steps {steps} (not in the first)"
        beta = np.concatenate(plan.selective)
        dt0 = min(float(g.rest_dt(r / (1.0 + b)).min()) for g, r, b in zip(self.groups, plan.rho, plan.selective))
        dt1 = min(float(g.rest_dt(r).min()) for g, r in zip(self.groups, plan.rho))
        dt0, dt1 = dt0 * plan.dt_safety, dt1 * plan.dt_safety
        tol, cap = plan.cg
        return (f"selective mass scaling (steps {steps}): translational mass as without it, added mass "
                f"{100 * plan.added_mass:.3g} % of the physical (uniform and selective) on {int((beta > 0).sum())} "
                f"of {len(beta)} elements "
                f"(beta up to {beta.max():.3g}), rest step {dt0:.4g} -> {dt1:.4g} s (x{dt1 / dt0:.3g}); "
                f"conjugate gradients per cycle, tolerance {tol:g}, cap {cap} iterations")


def build(cards: list, ctx) -> SelectiveMassEffect | None:
    """The effect, or None when no step is selective. cards: each step's ``mass_scaling`` card or None."""
    selective = [c is not None and c.is_selective for c in cards]
    if not any(selective):
        return None
    problems = []
    for i, on in enumerate(selective):
        if not on:
            continue
        path = ("steps", i, "mass_scaling", "selective" if cards[i].selective else "selective_target_dt")
        if ctx.rotations is not None:
            problems.append((path, "selective mass scaling is for hexahedra; this model has shell nodes with "
                             "rotations (use `factor` or `target_dt` without `selective`)"))
        for g in ctx.groups:
            if not g.solid:
                problems.append((path, f"selective mass scaling is for hexahedra; group {g.name} holds "
                                 f"{g.cell_type} elements"))
    if problems:
        raise CompileError(problems)
    return SelectiveMassEffect(ctx.groups, ctx.X, selective)


register_effect(EffectKind("mass_scaling", build))
