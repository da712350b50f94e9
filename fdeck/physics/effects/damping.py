"""Mass-proportional (Rayleigh alpha) damping, switched per step: f = -alpha m v (and m = -alpha I w on rotations).

Used to bring a structure to rest (static answers from an explicit code); its dissipated energy is booked in the
ledger so the balance still closes. Critical damping of a mode of angular frequency w is alpha = 2 w. When the
problem has rotational dofs (shells) the same alpha damps the angular velocities through the rotational inertia.
"""

from __future__ import annotations

from fdeck.engine.effect import Effect


class MassDamping(Effect):
    name = "damping"
    ledger = "damping"

    def __init__(self, mass, rotational: bool = False):
        self.mass = mass  # (n_node,) lumped mass actually used by the dynamics [t]
        self.alpha = 0.0  # [1/s], set by the engine at the start of each step
        self.rotational = rotational
        self.rot = None

    def bind(self, rotations) -> None:
        self.rot = rotations

    def add_force(self, t, x, v, f):
        if self.alpha > 0.0:
            f -= self.alpha * self.mass[:, None] * v
            if self.rot is not None:
                self.rot.m_damp -= self.alpha * self.rot.I[:, None] * self.rot.w
