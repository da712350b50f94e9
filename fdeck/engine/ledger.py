"""The energy ledger: named terms reported by element groups and effects, summed by kind, one history row by name.

A source (element group or effect) declares ``terms``, a tuple of ``Term``, and returns their current values from
``term_values()`` in the same order. Kinds:

* ``work``: energy put into the model from outside, cumulative since the start [mJ] (a tool's work on the blank);
* ``stored``: recoverable energy held now [mJ] (strain energy, hourglass springs, contact penalty springs);
* ``dissipated``: energy taken out of the model, cumulative [mJ] (friction, viscous hourglass);
* ``part``: a named share of a stored term, shown as a column but not summed again (a shell's bending energy);
* ``value``: any other history column (a tool's force and displacement) — not energy, not in the balance.

A term with ``rate=True`` reports a power [mW] instead; the ledger integrates it once per cycle (rectangle rule
over the averaged step, as the engine's own damping work) and shows the integral. Terms of the same name from
several sources are summed into one column (two sections' bending energies are one ``bending_energy``).

The engine books what it integrates itself: kinetic energy, the work of external forces and reactions, and the
dissipation of damping forces. The balance error is

    kinetic + sum(stored) + sum(dissipated) - external work - sum(work) - (its value at the first cycle),

which stays near zero when every force in the model is consistent with a booked energy (MODELS.md section 8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

WORK, STORED, DISSIPATED, PART, VALUE = "work", "stored", "dissipated", "part", "value"
KINDS = (WORK, STORED, DISSIPATED, PART, VALUE)

# Columns every history has, in this order (checks and regression gold read them by name).
CORE = ("time", "dt", "kinetic_energy", "internal_energy", "strain_energy", "hourglass_energy", "damping_energy",
        "external_work", "energy_balance_error")
# Stored terms with a core column of their own; every other term gets a column after the core ones.
CORE_STORED = ("strain_energy", "hourglass_energy")


@dataclass(frozen=True)
class Term:
    """One named entry of a source's ledger (see the module docstring for ``kind`` and ``rate``)."""

    name: str
    kind: str
    rate: bool = False

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"ledger term {self.name!r}: kind {self.kind!r} is not one of {KINDS}")
        if self.rate and self.kind not in (WORK, DISSIPATED):
            raise ValueError(f"ledger term {self.name!r}: only work and dissipation may be given as a rate")


class Ledger:
    """Collects the terms of ``sources`` (objects with ``terms`` and ``term_values()``) and builds history rows.

    ``extra`` names engine columns placed after the core ones (rotational kinetic energy, reactions).
    """

    def __init__(self, sources, extra: tuple[str, ...] = ()):
        self.sources = [s for s in sources if s.terms]
        kinds: dict[str, str] = {}
        for s in self.sources:
            for term in s.terms:
                if kinds.setdefault(term.name, term.kind) != term.kind:
                    raise ValueError(f"ledger term {term.name!r} is reported as {kinds[term.name]} and {term.kind}")
                if term.name in CORE and term.name not in CORE_STORED:
                    raise ValueError(f"ledger term {term.name!r} is an engine column")
        self.kinds = kinds
        own = [n for n in kinds if n not in CORE_STORED]
        self.columns = list(CORE) + list(extra) + own
        self.rated = [(s, [i for i, t in enumerate(s.terms) if t.rate]) for s in self.sources]
        self.rated = [(s, idx) for s, idx in self.rated if idx]
        self.integral = {id(s): [0.0] * len(s.terms) for s, _ in self.rated}

    def integrate(self, dt_avg: float) -> None:
        """Add dt_avg times the current power of every rate term (called once per cycle)."""
        for s, idx in self.rated:
            values, acc = s.term_values(), self.integral[id(s)]
            for i in idx:
                acc[i] += dt_avg * values[i]

    def state(self) -> list[list[float]]:
        """The integrals of the rate terms, in source order (for a checkpoint; ``integral`` is keyed by ``id``)."""
        return [list(self.integral[id(s)]) for s, _ in self.rated]

    def load_state(self, state: list[list[float]]) -> None:
        """Restore ``state()`` of a ledger over the same sources."""
        if len(state) != len(self.rated):
            raise ValueError(f"ledger state has {len(state)} rated sources, this ledger {len(self.rated)}")
        for (s, _), acc in zip(self.rated, state):
            self.integral[id(s)] = list(acc)

    def totals(self) -> dict[str, float]:
        """Current value of every term, by name (same names summed; rate terms integrated)."""
        out = dict.fromkeys(self.kinds, 0.0)
        out.update(dict.fromkeys(CORE_STORED, 0.0))
        for s in self.sources:
            acc = self.integral.get(id(s))
            for i, (term, value) in enumerate(zip(s.terms, s.term_values())):
                out[term.name] += acc[i] if term.rate else value
        return out

    def by_kind(self, totals: dict[str, float]) -> dict[str, float]:
        """Sums of the totals per kind (work, stored, dissipated)."""
        out = {WORK: 0.0, STORED: 0.0, DISSIPATED: 0.0}
        for name, value in totals.items():
            kind = self.kinds.get(name, STORED)  # the core stored columns
            if kind in out:
                out[kind] += value
        return out

    def row(self, t: float, dt: float, kinetic: float, external_work: float, damping: float, energy0: float,
            extra: list[float], totals: dict[str, float] | None = None) -> tuple[list[float], float]:
        """(history row in ``columns`` order, balance error) at time t."""
        totals = self.totals() if totals is None else totals
        k = self.by_kind(totals)
        error = kinetic + k[STORED] + k[DISSIPATED] + damping - external_work - k[WORK] - energy0
        row = [t, dt, kinetic, k[STORED], totals["strain_energy"], totals["hourglass_energy"], damping,
               external_work, error] + list(extra)
        row += [totals[n] for n in self.columns[len(CORE) + len(extra):]]
        return row, error

    def energy(self, kinetic: float) -> float:
        """kinetic + stored + dissipated - work of the sources (no engine terms): the first cycle's reference."""
        k = self.by_kind(self.totals())
        total = kinetic + k[STORED] + k[DISSIPATED] - k[WORK]
        if not math.isfinite(total):
            return math.nan
        return total
