"""What the engine needs from an effect (boundary condition, load, damping, section add-on).

An effect is built by the compiler only when the deck names it. The engine calls, per cycle:
``add_force(t, x, v, f)`` for effects with ``ledger`` in {"external", "damping", "internal"}: the effect adds its
nodal forces [N] to f (n_node, 3), the array of that ledger entry (internal forces carry the resisting sign);
``constrain(t_next, dt, x, v)`` for effects with ``constrains = True``: overwrite prescribed velocities
v (n_node, 3) [mm/s] at the half step so that positions at t_next are as prescribed.
Internal effects report their stored energy [mJ] through ``energy()`` and their step limit through
``stable_dt()``. An internal effect with an ``energy_column`` (e.g. "bending_energy") gets that history column of its
own (effects sharing a name are summed), so its share of the internal energy stays visible in the ledger.
"""

from __future__ import annotations

import numpy as np


class Effect:
    name = "effect"
    ledger: str | None = None  # "external", "damping", "internal" or None (constraint only)
    constrains = False
    energy_column: str | None = None  # own history column for an internal effect's stored energy

    def add_force(self, t: float, x: np.ndarray, v: np.ndarray, f: np.ndarray) -> None:
        pass

    def constrain(self, t_next: float, dt: float, x: np.ndarray, v: np.ndarray) -> None:
        pass

    def energy(self) -> float:
        return 0.0

    def stable_dt(self) -> float:
        return np.inf
