"""Mass-proportional (Rayleigh alpha) damping, switched per step: f = -alpha m v (and m = -alpha I w on rotations).

Used to bring a structure to rest (static answers from an explicit code); its dissipated energy is booked in the
ledger so the balance still closes. Critical damping of a mode of angular frequency w is alpha = 2 w. When the
problem has rotational dofs (shells) the same alpha damps the angular velocities through the rotational inertia.
A step setting (``steps[i].damping``): built only when some step asks for it.
"""

from __future__ import annotations

from fdeck.engine.effect import Effect
from fdeck.registry import EffectKind, register_effect


class MassDamping(Effect):
    deck_settings = ("alphas",)  # per step, from the deck: not saved (engine.snapshot)
    name = "damping"
    forces = "damping"

    def __init__(self, alphas: list[float], rotational: bool = False):
        self.alphas = alphas  # [1/s] per step
        self.alpha = 0.0
        self.mass = None  # (n_node,) lumped mass of the current step [t]
        self.rotational = rotational
        self.rot = None

    def bind(self, rotations) -> None:
        self.rot = rotations

    def begin_step(self, index, plan):
        self.alpha, self.mass = self.alphas[index], plan.mass

    def add_force(self, t, x, v, f):
        if self.alpha > 0.0:
            f -= self.alpha * self.mass[:, None] * v
            if self.rot is not None:
                self.rot.m_damp -= self.alpha * self.rot.I[:, None] * self.rot.w


def build(cards: list, ctx) -> MassDamping | None:
    """The effect, or None when no step damps. cards: each step's ``damping`` card or None."""
    alphas = [c.mass_proportional if c is not None else 0.0 for c in cards]
    if not any(a > 0 for a in alphas):
        return None
    return MassDamping(alphas, rotational=ctx.rotations is not None)


register_effect(EffectKind("damping", build))
