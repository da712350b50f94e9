"""Mass-proportional (Rayleigh alpha) damping, switched per step: f = -alpha m v.

Used to bring a structure to rest (static answers from an explicit code); its dissipated energy is booked in the
ledger so the balance still closes. Critical damping of a mode of angular frequency w is alpha = 2 w.
"""

from __future__ import annotations

from fdeck.engine.effect import Effect


class MassDamping(Effect):
    name = "damping"
    ledger = "damping"

    def __init__(self, mass):
        self.mass = mass  # (n_node,) lumped mass actually used by the dynamics [t]
        self.alpha = 0.0  # [1/s], set by the engine at the start of each step

    def add_force(self, t, x, v, f):
        if self.alpha > 0.0:
            f -= self.alpha * self.mass[:, None] * v
