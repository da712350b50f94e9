"""Card of a step's mass scaling (``steps[i].mass_scaling``): conventional (density) or selective; the selective
kind runs in the engine as an effect (``physics.effects.selective_mass``), built only when a step asks for it."""

from __future__ import annotations

from pydantic import Field, model_validator

from fdeck.deck.base import Card
from fdeck.registry import CardEntry, register_card

CG_TOLERANCE = 1e-3
"""Default relative tolerance of the selective-mass solve. Against 1e-4 (the default until 2026-11-28) it costs
21-38 % fewer iterations per cycle; the coarse tetrahedron's mean punch force moved by -0.18 %, every other answer
measured by at most 6e-4 (coarse tetrahedron and 0/90 double dome: energies, friction, draw-in, the dome's punch
force; 3WEAVE cantilevers: tip deflection within 1e-5; README, *Fewer cycles*). The residual is measured against
the net force of the cycle, which a quasi-static run keeps small, so the error it leaves is a small fraction of the
inertia, not of the forces that form the part."""
CG_MAX_ITERATIONS = 200
"""Default iteration cap of the selective-mass solve per cycle."""


class MassScaling(Card):
    """Mass scaling: a fixed density factor, or per-element added mass to reach a target time step."""

    factor: float | None = Field(None, ge=1.0, description="Density multiplier (dt grows by sqrt(factor)).")
    target_dt: float | None = Field(None, gt=0, description="Target stable time step [s]; mass is added to "
                                    "elements whose rest stable step is smaller, and the added mass is reported.")
    selective: bool = Field(False, description="Selective mass scaling (hexahedra): the mass is added only to the "
                            "modes that deform an element, not to its translation (Olovsson, Simonsson & Unosson "
                            "2005), so total mass, momentum and the slow bending modes stay as they are; the "
                            "non-diagonal mass is solved each cycle by conjugate gradients.")
    selective_target_dt: float | None = Field(
        None, gt=0, description="Selective mass scaling ON TOP of `factor` or `target_dt` [s]: after the uniform "
        "scaling (the one a deck was validated with, e.g. the published factor of a forming set-up), elements whose "
        "step is below this target get added mass on their deformation modes only, so the uniform translational "
        "inertia stays and the step grows further. Not with `selective`.")
    track_target: bool | float = Field(
        False, description="Selective scaling with a target (`selective_target_dt`, or `target_dt` with "
        "`selective`): keep the step at the target DURING the step (`true`), or at least at a lower floor "
        "(a step [s], at most the target: less mass, so a more quasi-static blank). The target is met at rest; an "
        "element whose step "
        "then falls below it (fibres stiffening in tension, a compacted ply) gets more added mass on its deformation "
        "modes at once, 5 % above what it needs; never for a step above what the effects allow anyway (contact "
        "penalty springs), nor above 0.8 of the step that fibre bending's hinges allow (they turn whole elements, "
        "which added mass does not slow). The kinetic energy that mass brings is booked as work "
        "(`mass_tracking_work`), the added mass is a history column (`tracked_added_mass`, per cent of the "
        "physical mass). LS-DYNA adds conventional mass during a run in the same way (negative DT2MS).")
    track_momentum: bool = Field(
        False, description="With `track_target`: when tracking adds mass, the velocities are corrected (one more "
        "conjugate-gradient solve on that cycle) so that the momentum of every dof, (M + dM) v, is what it was "
        "before: the new mass joins at rest relative to its element's rigid motion, the deformation modes slow down "
        "and the kinetic energy that removes is booked (`mass_tracking_work` falls). Without it the new mass takes "
        "the current velocities and the kinetic energy it carries is created (booked as positive work): an element "
        "crushed fast gets mass at its crushing speed, which can crush it further. Off by default so runs measured "
        "before it keep their numbers; the 3 mm tetrahedron on `ans_tbar` failed with and without it until the added "
        "mass's rigid modes followed the elements (README, Forming).")
    cg_tolerance: float = Field(
        CG_TOLERANCE, gt=0, lt=1, description="Selective scaling: the conjugate-gradient solve stops when the "
        "residual's norm (weighted by the inverse diagonal) falls below this fraction of the right-hand side's (the "
        "cycle's net force) [-]; against 1e-4 the default 1e-3 took 21-38 % fewer iterations and moved the answers "
        "measured by at most 0.2 %.")
    cg_max_iterations: int = Field(
        CG_MAX_ITERATIONS, ge=1, description="Selective scaling: iteration cap of the solve per cycle; a cycle that "
        "reaches it is counted and reported, not stopped.")

    @model_validator(mode="after")
    def _one_of(self):
        if (self.factor is None) == (self.target_dt is None):
            raise ValueError("give exactly one of `factor` or `target_dt`")
        if self.selective and self.selective_target_dt is not None:
            raise ValueError("`selective: true` makes `factor`/`target_dt` selective; `selective_target_dt` adds "
                             "selective scaling on top of a uniform one: give one of them")
        if self.track_target and not (self.selective_target_dt is not None
                                      or (self.selective and self.target_dt is not None)):
            raise ValueError("`track_target` keeps a selective target during the step: give `selective_target_dt`, "
                             "or `target_dt` with `selective: true`")
        if self.track_momentum and not self.track_target:
            raise ValueError("`track_momentum` corrects the velocities when tracking adds mass: give `track_target`")
        if not isinstance(self.track_target, bool) and not 0 < self.track_target <= self.selective_target:
            raise ValueError(f"`track_target` as a step must lie in (0, {self.selective_target:g}] s, the "
                             "selective target (it is the floor kept below it)")
        return self

    @property
    def selective_target(self) -> float | None:
        """The step [s] selective scaling aims at (None: a factor, no target)."""
        if self.selective_target_dt is not None:
            return self.selective_target_dt
        return self.target_dt if self.selective else None

    @property
    def tracked_dt(self) -> float | None:
        """The step [s] kept during the step by added mass (None: not tracked)."""
        if self.track_target is False:
            return None
        return self.selective_target if self.track_target is True else float(self.track_target)

    @property
    def is_selective(self) -> bool:
        """Whether the step has a non-diagonal added mass (either form)."""
        return self.selective or self.selective_target_dt is not None


register_card(CardEntry("mass_scaling", MassScaling, "effect", "step"))
