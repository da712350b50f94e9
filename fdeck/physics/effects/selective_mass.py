"""Selective mass scaling as a step setting (``steps[i].mass_scaling.selective``): the engine's added-mass solve
(``engine.selective_mass``) wrapped as an effect, built only when some step asks for it.

The step plan (``compile.problem.plan_steps``) gives each element its factor beta_e (from ``target_dt`` or
``factor``, the same element steps as conventional mass scaling); this effect holds the solver state (saved in
checkpoints with the effect), the prescribed-dof mask of the step, and reports: the added kinetic energy
1/2 v^T dM v (a share of the engine's ``kinetic_energy``, shown, not summed again), the mean and largest
conjugate-gradient iterations per cycle so far, and the cycles that reached the iteration cap.

With ``track_target`` the step's target is kept during the step (``track``): the engine hands over the groups'
element steps each cycle; elements below the target get their density (and so beta_e) raised to reach it with
``HEADROOM``, the conjugate-gradient preconditioner follows, and the kinetic energy the new mass carries at that
moment, 1/2 dc_e |(I - P_e) v_e|^2, is booked as work (``mass_tracking_work``): the balance stays closed. Only the
deformation modes get the mass, so momentum and translational inertia stay those of the step's lumped mass.

That booked energy is created: an element crushed fast gets mass at its crushing speed, and the energy can crush
it further (the 3 mm tetrahedron on ``ans_tbar`` blew up at 52.5 mm with kinetic energy and booked work growing
together). With ``track_momentum`` the raise instead keeps the momentum of every free dof, (M + dM) v, by one more
solve (``SelectiveMass.conserve``): the new mass joins at rest relative to its element's rigid motion, the
deformation modes slow, and the energy change booked is at most zero where no dof is prescribed (a prescribed
velocity still gives the new mass its own share). That deck still failed with it, earlier: the cause was the added
mass's rigid modes taken at the reference positions (``engine.selective_mass``, "Why the current rigid modes").

The rigid modes follow the elements (``follow``, every cycle before the forces): the kinetic energy of the added
mass that moving them changes at the half-step velocities is booked as ``mass_corotation_work``.

``ke`` (the ``added_kinetic_energy`` term) is computed on the cycles that write a history row (and the first):
between rows it holds the last row's value, which nothing reads (``engine.selective_mass.SelectiveMass.book``).

With fibre bending the hinges turn whole elements, which the added mass does not slow: an element's step is
2 / sqrt(omega_g^2 + omega_b^2) with omega_b^2 the hinges' (against the translational mass) and omega_g^2 the
continuum's, which the mass divides. Tracking then keeps at most ``REACH`` of the hinges' own current step (the
engine caps the target there), and gives each element the continuum step 2 / sqrt(omega_t^2 - omega_b^2) that
brings the sum to the target's omega_t (``compile.problem.selective_density`` does the same at rest).
"""

from __future__ import annotations

import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect, free_dofs
from fdeck.engine.ledger import VALUE, WORK, Term
from fdeck.engine.selective_mass import SelectiveMass
from fdeck.engine.step_mass import same_masses
from fdeck.registry import EffectKind, register_effect


TOLERANCE = 1e-9
"""Relative shortfall of an element step below the target that counts: the plan meets the target to round-off."""

HEADROOM = 1.05
"""A tracked element's step is raised to 1.05 x the target: it then stiffens by about 10 % before it needs mass
again, so each element is re-scaled every few hundred cycles rather than every cycle. Late in a forming stroke
some element of a large blank still falls below the target on most cycles, so a raise costs O(raised elements)
(``track``; with fibre bending the hinges' step update that follows it still passes over every element)."""

REACH = 0.8
"""With fibre bending, the tracked step is kept at most at 0.8 x the hinges' own step: an element whose hinges alone
allow omega_b then needs its continuum slowed to omega_t sqrt(1 - 0.64) = 0.6 omega_t (beta ~ 3 (omega_g /
omega_t)^2), where a target at the hinges' bound itself would need an infinite mass."""


class SelectiveMassEffect(Effect):
    # per step, from the deck: not saved (engine.snapshot)
    deck_settings = ("selective", "targets", "momentum_steps", "momentum")
    name = "selective_mass"
    solves_mass = True  # the engine hands it the accelerations of every cycle (``engine.solver``)
    terms = (Term("added_kinetic_energy", VALUE), Term("cg_iterations_mean", VALUE),
             Term("cg_iterations_max", VALUE), Term("cg_capped_cycles", VALUE), Term("mass_corotation_work", WORK))
    tracking_terms = (Term("mass_tracking_work", WORK), Term("tracked_added_mass", VALUE),
                      Term("tracked_elements", VALUE))

    def __init__(self, groups: list, X: np.ndarray, selective: list[bool], targets: list[float | None],
                 stiff: list = (), momentum: list[bool] | None = None):
        self.solver = SelectiveMass([g.conn for g in groups], X)
        self.groups = groups
        self.selective = selective
        self.targets = targets  # per step: the step kept during it [s], or None
        self.momentum_steps = list(momentum) if momentum is not None else [False] * len(targets)
        self.momentum = False  # this step's: tracking keeps (M + dM) v (``SelectiveMass.conserve``)
        if any(t is not None for t in targets):
            self.terms = self.terms + self.tracking_terms
        self.physical = sum(float(g.mass(g.rho).sum()) for g in groups)  # [t], before any scaling
        # element mass per unit density (n_el,) [mm^3] of each group: the lumped mass is linear in the density
        self.unit_mass = [g.mass(np.ones(len(g.conn))).sum(axis=1) for g in groups]
        for a in self.unit_mass:
            a.flags.writeable = False  # a constant: not saved with checkpoints (engine.snapshot)
        self.offsets = np.cumsum([0] + [len(g.conn) for g in groups])
        self.plan = None
        self.track_dt = None
        self.ke = 0.0
        self.tracking_work = 0.0  # [mJ] cumulative
        self.corotation_work = 0.0  # [mJ] cumulative, what ``follow`` changed in the added kinetic energy
        self.tracked_mass = 0.0  # [t] added by tracking, as the plan counts added mass (trace share)
        self.tracked = np.zeros(self.offsets[-1], bool)  # elements given mass by tracking (ever)
        # per group (n_el,): the density tracking added during this step [t/mm^3], carried into a next step that
        # tracks too (its elements are as stiff as they were), dropped before one that does not
        self.extra = [np.zeros(len(g.conn)) for g in groups]
        self.carry = False
        self.stiff = list(stiff)  # effects with a stiffness on element rotations (``own_omega2``): step bounds too

    def begin_step(self, index, plan):
        # the tracked mass carries where the next step tracks the same target on the same plan (a dwell after the
        # stroke); with another target or plan the densities it was measured against are gone: tracking restarts
        self.carry = (index > 0 and self.targets[index] is not None and self.targets[index] == self.targets[index - 1]
                      and self.plan is not None and same_masses(self.plan, plan))
        self.plan = plan
        self.track_dt = self.targets[index]
        self.momentum = self.momentum_steps[index]
        if not self.carry:
            self.tracked_mass = 0.0
            for a in self.extra:
                a.fill(0.0)

    @property
    def active(self) -> bool:
        return self.plan is not None and self.plan.selective is not None

    def prepare(self, constraints: list, x: np.ndarray) -> None:
        """Set the step up (called by the engine after ``begin_step``): the prescribed dofs are those the
        constraints write (found by letting them write into NaNs; translational constraints only, as selective
        scaling is refused with rotations)."""
        if self.plan.selective is None:  # a step without selective mass after one with it: lumped mass only
            self.solver.set_step(None, [], self.plan.mass, None, self.plan.cg)
            self.ke = 0.0
            return
        free = free_dofs(constraints, x)
        # the rigid modes at the step's start positions (a step without selective mass before this one left them
        # where they were; where they are current already this changes no bit); set_step rebuilds the preconditioner
        self.solver.follow(x, np.zeros_like(x), precondition=False)
        # element masses of the translational (base) density rho / (1 + beta): physical, or uniformly scaled
        base = [g.mass(r / (1.0 + b)).sum(axis=1) for g, r, b in zip(self.groups, self.plan.rho, self.plan.selective)]
        self.solver.set_step(self.plan.selective, base, self.plan.mass, free, self.plan.cg)
        if self.carry:  # the last step's tracked mass, on top of this step's own (engine.step_mass books any change)
            for i, (g, extra) in enumerate(zip(self.groups, self.extra)):
                low = np.flatnonzero(extra > 0.0)
                if len(low):
                    g.rho[low] += extra[low]
                    self.solver.add(self.offsets[i] + low, extra[low] * self.unit_mass[i][low] / g.conn.shape[1])

    def term_values(self) -> tuple[float, ...]:
        s = self.solver
        values = (self.ke, s.iterations / max(s.cycles, 1), float(s.max_iterations), float(s.capped),
                  self.corotation_work)
        if len(self.terms) > len(values):
            values += (self.tracking_work, 100.0 * self.tracked_mass / self.physical, float(self.tracked.sum()))
        return values

    def follow(self, x: np.ndarray, v: np.ndarray) -> None:
        """Every cycle before the forces at t_n+1 (the damping of the added mass reads dM there): the added mass's
        rigid modes move to the positions x (n_node, 3) [mm] (``SelectiveMass.follow``); the kinetic energy that
        changes at the half-step velocities v (n_node, 3) [mm/s] is booked as ``mass_corotation_work``."""
        self.corotation_work += self.solver.follow(x, v)

    reach = REACH  # (the engine's cap on the target with hinges)

    def rotation_omega2(self) -> list:
        """Per group, the hinges' squared frequencies omega_b^2 (n_el,) [1/s^2] on element rotations at their last
        ``stable_dt`` (summed over the effects on that group), or None where no such effect acts."""
        out = [None] * len(self.groups)
        for e in self.stiff:
            i = e.group_index
            out[i] = e.rotation_omega2() if out[i] is None else out[i] + e.rotation_omega2()
        return out

    def track(self, group_dt: list[float], keep: float, safety: float, v: np.ndarray, v_old: np.ndarray,
              rotation_omega2: list | None = None, forces: tuple | None = None, dt: float = 0.0) -> list[float]:
        """Keep the step at ``keep`` [s] (``track_dt``, or less where an effect such as contact bounds the step
        anyway: mass beyond that would slow the blank and buy nothing): every element whose continuum step (dt_e,
        as the group computed it this cycle) is below its target gets the density rho_e (HEADROOM target_e /
        dt_e)^2, i.e. more mass on its deformation modes only (translational mass unchanged). The target is
        keep / safety, or with the hinges' omega_b^2 of ``rotation_omega2`` (per group, (n_el,) or None) the
        continuum step 2 / sqrt(omega_t^2 - omega_b^2) that brings the element to keep / safety (the engine keeps
        omega_t above omega_b). With ``track_momentum`` the velocities v are then corrected (``SelectiveMass.conserve``;
        forces = (f_ext, f_int, f_damp) at t_n+1 and dt the step just taken, for its booking). Returns the groups'
        new smallest continuum steps [s]."""
        target = keep / safety  # element step to reach [s]
        out = list(group_dt)
        raised = []  # (elements, added c_e) per group, for the momentum correction
        for i, g in enumerate(self.groups):
            wb2 = None if rotation_omega2 is None else rotation_omega2[i]
            if wb2 is None:
                goal, ample = target, HEADROOM * target
            else:  # the continuum's share of the target (hinges' frequencies add in squares, module docstring);
                # the headroom on the element's whole step: at the engine's cap (wb2 <= REACH^2 omega_t^2) its
                # continuum still has (1 / HEADROOM^2 - REACH^2) omega_t^2 = 0.27 omega_t^2 left
                goal = 2.0 / np.sqrt((2.0 / target) ** 2 - wb2)
                ample = 2.0 / np.sqrt((2.0 / (HEADROOM * target)) ** 2 - wb2)
            below = goal * (1.0 - TOLERANCE)
            low = np.flatnonzero(g.dt_e < below)
            if not len(low):
                continue
            factor = ((ample if wb2 is None else ample[low]) / g.dt_e[low]) ** 2
            drho = g.rho[low] * (factor - 1.0)
            g.rho[low] += drho  # the group's own array (``set_density`` copies the plan's)
            self.extra[i][low] += drho
            de = drho * self.unit_mass[i][low]  # added element mass [t]
            n = g.conn.shape[1]
            if self.momentum:  # the velocities are corrected once, after every group's raise
                self.solver.add(self.offsets[i] + low, de / n)
                raised.append((self.offsets[i] + low, de / n))
            else:
                self.tracking_work += self.solver.add(self.offsets[i] + low, de / n, v, v_old)
            self.tracked_mass += float(de.sum()) * (1.0 - 2.0 / n)  # the plan's trace measure of added mass
            self.tracked[self.offsets[i] + low] = True
            # the step goes as sqrt(rho) at fixed moduli: the raised elements' steps without a pass over all
            g.dt_e[low] *= np.sqrt(factor)
            out[i] = float(g.dt_e.min())
        if raised:
            idx, dc = (np.concatenate(a) for a in zip(*raised))
            net = None if forces is None else forces[0] - forces[1] + forces[2]
            self.tracking_work += self.solver.conserve(idx, dc, v, net, dt)
        return out

    def describe(self, plan) -> str | None:
        steps = [i for i, on in enumerate(self.selective) if on]
        if plan.selective is None:
            return f"selective mass scaling in steps {steps} (not in the first)"
        from fdeck.compile.problem import rest_dt

        beta = np.concatenate(plan.selective)
        base = [plan.translational(i) for i in range(len(self.groups))]
        dt0 = min(float(rest_dt(g, b, self.stiff).min()) for g, b in zip(self.groups, base))
        dt1 = min(float(rest_dt(g, r, self.stiff, b).min()) for g, r, b in zip(self.groups, plan.rho, base))
        dt0, dt1 = dt0 * plan.dt_safety, dt1 * plan.dt_safety
        tol, cap = plan.cg
        tracked = [i for i, t in enumerate(self.targets) if t is not None]
        keep = f"; the target is kept during steps {tracked} (more mass as elements stiffen)" if tracked else ""
        if tracked and self.stiff:
            keep += f", at most {REACH:g} of the step the hinges of {', '.join(e.name for e in self.stiff)} allow"
        corrected = [i for i in tracked if self.momentum_steps[i]]
        if corrected:
            keep += f"; velocities corrected as mass is added ((M + dM) v kept, track_momentum) in steps {corrected}"
        return (f"selective mass scaling (steps {steps}): translational mass as without it, added mass "
                f"{100 * plan.added_mass:.3g} % of the physical (uniform and selective) on {int((beta > 0).sum())} "
                f"of {len(beta)} elements "
                f"(beta up to {beta.max():.3g}), rest step {dt0:.4g} -> {dt1:.4g} s (x{dt1 / dt0:.3g}); "
                f"conjugate gradients per cycle, tolerance {tol:g}, cap {cap} iterations{keep}")


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
    own = [e for e in ctx.effects if hasattr(e, "own_omega2")]  # stiffness on element rotations (fibre bending)
    if problems:
        raise CompileError(problems)
    targets = [c.tracked_dt if on else None for c, on in zip(cards, selective)]
    momentum = [bool(on and c.track_momentum) for c, on in zip(cards, selective)]
    return SelectiveMassEffect(ctx.groups, ctx.X, selective, targets, own, momentum)


register_effect(EffectKind("mass_scaling", build))
