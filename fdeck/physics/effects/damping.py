"""Mass-proportional (Rayleigh alpha) damping, switched per step: f = -alpha m v (and m = -alpha I w on rotations).

Used to bring a structure to rest (static answers from an explicit code); its dissipated energy is booked in the
ledger so the balance still closes. Critical damping of a mode of angular frequency w is alpha = 2 w. When the
problem has rotational dofs (shells) the same alpha damps the angular velocities through the rotational inertia.
A step setting (``steps[i].damping``): built only when some step asks for it.

With ``added_mass`` and selective mass scaling (``engine.selective_mass``) the force is -alpha (M + dM) v: the added
mass sits on each element's deformation modes (dM annihilates rigid motion), so those modes, which carry it,
decay at alpha like the rest. Without it they are damped by their lumped share only, about 1 + beta times slower:
after the 5 mm tetrahedron's stroke (added mass 248x the physical) a dwell with deformation damping, which also
acts on the lumped mass, left 13.9 mJ ringing in the added mass against the unscaled run's 0.66 mJ (README).
"""

from __future__ import annotations

from fdeck.compile.errors import CompileError
from fdeck.engine.effect import Effect
from fdeck.registry import EffectKind, register_effect


class MassDamping(Effect):
    deck_settings = ("alphas", "added", "sms")  # per step from the deck, and a link: not saved (engine.snapshot)
    name = "damping"
    forces = "damping"

    def __init__(self, alphas: list[float], rotational: bool = False, added: list[bool] | None = None):
        self.alphas = alphas  # [1/s] per step
        self.added = added or [False] * len(alphas)  # per step: damp the selective added mass too
        self.alpha = 0.0
        self.with_added = False
        self.mass = None  # (n_node,) lumped mass of the current step [t]
        self.rotational = rotational
        self.rot = None
        self.sms = None  # the selective mass effect (``bind_selective``), when the problem has one

    def bind(self, rotations) -> None:
        self.rot = rotations

    def bind_selective(self, sms) -> None:
        self.sms = sms

    def begin_step(self, index, plan):
        self.alpha, self.mass = self.alphas[index], plan.mass
        self.with_added = self.added[index]

    def add_force(self, t, x, v, f):
        if self.alpha > 0.0:
            f -= self.alpha * self.mass[:, None] * v
            if self.with_added:  # build() refuses it in a step without selective mass, so sms is bound and active
                y = self.sms.solver.product(v)  # the solver's buffer: scaled in place, no temporary
                y *= self.alpha
                f -= y
            if self.rot is not None:
                self.rot.m_damp -= self.alpha * self.rot.I[:, None] * self.rot.w


def build(cards: list, ctx) -> MassDamping | None:
    """The effect, or None when no step damps. cards: each step's ``damping`` card or None."""
    alphas = [c.mass_proportional if c is not None else 0.0 for c in cards]
    added = [c is not None and c.added_mass for c in cards]
    problems = [(("steps", i, "damping", "added_mass"), "damping of the added mass needs selective mass scaling "
                 "in the same step (mass_scaling with `selective` or `selective_target_dt`)")
                for i, (on, step) in enumerate(zip(added, ctx.deck.steps))
                if on and (step.mass_scaling is None or not step.mass_scaling.is_selective)]
    if problems:
        raise CompileError(problems)
    if not any(a > 0 for a in alphas):
        return None
    return MassDamping(alphas, rotational=ctx.rotations is not None, added=added)


register_effect(EffectKind("damping", build))
