"""What the engine needs from an effect (boundary condition, load, damping, section add-on, tool contact).

An effect is built by the compiler only when the deck names it. Per cycle n -> n+1 the engine calls, in this order:

1. ``begin_step(k, plan)`` once at the start of step k (``plan`` a ``compile.problem.StepPlan``: densities, nodal
   mass, damping factor of the step);
2. ``constrain(t_next, dt, x, v)`` for effects with ``constrains = True``: overwrite prescribed velocities
   v (n_node, 3) [mm/s] at the half step so that positions at t_next are as prescribed;
3. ``advance(t_next, dt, dt_avg)`` for effects with ``moves = True``: move the effect's own bodies (a rigid tool)
   to t_next, before the blank's forces there are computed;
4. ``add_force(t, x, v, f)`` for effects with ``forces`` set: add nodal forces [N] at (t, x, v) to f (n_node, 3),
   the engine array named by ``forces``:
   - "external": a load; the engine integrates its work into ``external_work``;
   - "damping": a dissipative force; the engine integrates its work into ``damping_energy``;
   - "internal": a force with the resisting sign (f_int) whose energy the effect books itself in its ``terms``
     (a stored spring energy, a friction dissipation, a tool's work);
5. ``stable_dt()``: the effect's own limit on the time step [s] (inf when none).

A section add-on names the element ``group`` it acts on; if it has a stiffness of its own, ``rest_dt(rho)`` gives
the rest steps (n_el,) [s] of that group's elements with it, for mass scaling and ``fdeck info``, and
``element_dt()`` their current steps after its ``stable_dt`` (for subcycling's levels; None otherwise). A stiffness
that turns whole elements (fibre bending's hinges) also gives ``own_omega2(rho)``, its own squared frequency bound
per element against the lumped mass of densities rho, which selective mass scaling counts against the
translational mass only (``compile.problem.selective_density``).

Ledger: ``terms`` (tuple of ``engine.ledger.Term``) and ``term_values()`` give the effect's named energies and
history columns (see ``engine.ledger``). Checkpoints save an effect's mutable state by walking its attributes
(``engine.snapshot``: writeable arrays and plain scalars); an effect whose state lives elsewhere (a cache that must
be rebuilt, an external handle) defines ``state()`` and ``load_state(state)`` instead. Rotational effects
(``rotational = True``) are bound once to the nodal rotations with ``bind(rotations)``.
"""

from __future__ import annotations

import numpy as np

from fdeck.engine.ledger import Term


def free_dofs(constraints: list, x: np.ndarray) -> np.ndarray:
    """(n_node, 3) 1.0 on the translational dofs no constraint writes, 0.0 on the prescribed ones (found by
    letting the constraints write into NaNs)."""
    probe = np.full(x.shape, np.nan)
    for c in constraints:
        c.probe(x.copy(), probe)
    return np.isnan(probe).astype(float)


class Effect:
    name = "effect"
    forces: str | None = None  # "external", "damping", "internal" or None (no forces)
    constrains = False
    moves = False
    rotational = False
    # internal forces the subcycled loop (engine.subcycle) may evaluate at every minor step: any stiffness of the
    # effect reaches the levels through ``element_dt`` or ``node_dt`` (fibre bending, contact, a tool)
    subcycling_safe = False
    terms: tuple[Term, ...] = ()
    group = None  # the element group of a section add-on

    def begin_step(self, index: int, plan) -> None:
        pass

    def constrain(self, t_next: float, dt: float, x: np.ndarray, v: np.ndarray) -> None:
        pass

    def probe(self, x: np.ndarray, v: np.ndarray) -> None:
        """Write into the translational velocities v (n_node, 3) what ``constrain`` writes there, changing nothing
        else (``free_dofs``); a constraint whose ``constrain`` has side effects (an integrated angle) overrides it."""
        self.constrain(0.0, 1.0, x, v)

    def advance(self, t_next: float, dt: float, dt_avg: float) -> None:
        pass

    def add_force(self, t: float, x: np.ndarray, v: np.ndarray, f: np.ndarray) -> None:
        pass

    def term_values(self) -> tuple[float, ...]:
        return ()

    def stable_dt(self) -> float:
        return np.inf

    def bind(self, rotations) -> None:
        pass

    def rest_dt(self, rho: np.ndarray) -> np.ndarray | None:
        return None

    def element_dt(self) -> np.ndarray | None:
        return None

    def node_dt(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(nodes (k,), steps (k,) [s]) for an effect that is a spring on single nodes (contact): each node's own
        step bound with the current step's masses, for subcycling's node levels; None otherwise."""
        return None

    def check_plan(self, plans) -> list[str]:
        """Problems that only the step plan reveals (masses after mass scaling, a tool's speed in each step): plain
        messages, reported by the compiler at the effect's deck path (``path``) as input errors."""
        return []

    def describe(self, plan) -> str | None:
        """One line for ``fdeck info`` (what the effect acts on, its laws, its step bound with the step plan ``plan``),
        or None when its name says enough."""
        return None

    def node_fields(self) -> dict[str, tuple[np.ndarray, np.ndarray, str, float]]:
        """Nodal fields of the effect for every frame: {name: (nodes (k,), values (k,), merge, elsewhere)}, merge
        "max" or "min" naming how the values of several effects at one node combine (a NaN wins), ``elsewhere`` the
        value at nodes no effect gives; empty by default."""
        return {}

    def surfaces(self) -> list[tuple[str, np.ndarray, np.ndarray]]:
        """Surfaces of the effect's own bodies to draw beside the blank in every frame (a rigid tool): a list of
        (name, current points (n, 3) [mm], triangles (m, 3) int, 0-based); empty for effects without a body."""
        return []
