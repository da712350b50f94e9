"""Which force source leaks energy? The energy balance of a run, split by source.

    python studies/ledger_closure.py DECK [--study STUDY.yaml --variant NAME] [--rows 12]

Runs DECK (or the variant NAME of a study deck, resolved as ``fdeck study`` does) in-process and, for every element
group and every effect that adds forces, integrates the work of its own nodal forces on the blank over the run
(trapezoidal in the positions, as the engine's central differences do) and compares it with what the source books
in the energy ledger (its stored plus dissipated energy minus its own work terms). For a consistent source the two
agree to the integrator's error; the table prints, at a dozen history rows, the run's balance error and each
source's closure, booked change plus the work of its forces on the blank (mJ; a source whose work the engine books
itself, a load or damping, shows that work; the closures of the other sources sum to the balance error less the
integrator's share: kinetic energy against the work of all forces, the selective mass solve's residual). A source
with a large closure is the one whose forces and booked energies disagree. For a contact the closure without its
``contact_area_work`` is printed beside it: what the balance would lack without that term.

Diagnostic only: each source's force array is copied once per cycle (some tens of microseconds per cycle for 10^4
nodes, serial numpy), so the elements' parallel share of the cycle shrinks and one thread (``NUMBA_NUM_THREADS=1``)
wastes little. It wraps the sources' ``add_forces`` / ``add_force`` and the first group's ``update`` (which sees
each cycle's positions), so it follows the engine's uniform loop (``engine.solver``): refused for subcycled steps,
and for shells with rotations (the work of moments is not counted).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from fdeck.compile.problem import compile_deck
from fdeck.deck.loader import load_file
from fdeck.deck.model import Deck
from fdeck.engine import solver
from fdeck.engine.ledger import DISSIPATED, STORED, WORK


def load(deck: Path | None, study: Path | None, variant: str | None) -> tuple[dict, Path]:
    """(deck data, folder its relative paths start from): DECK, or the variant of a study as ``fdeck study`` plans
    it (listed or grid variants; the study file checked with located messages)."""
    if study is None:
        data, _ = load_file(deck)
        return data, deck.parent
    from fdeck.study.study import load_study

    _, planned = load_study(study)
    names = [p.name for p in planned]
    if variant not in names:
        raise SystemExit(f"{study}: no variant {variant!r}; its variants: {', '.join(names)}")
    chosen = planned[names.index(variant)]
    return chosen.deck, chosen.base_dir


def booked(source) -> tuple[float, float]:
    """(stored + dissipated - work, contact_area_work) of a source's ledger terms [mJ], from one call of its
    ``term_values``; rate terms (a power the engine's ledger integrates: a viscous hourglass's dissipation) are left
    out, so such a source's closure includes them (``main`` names them)."""
    total = area = 0.0
    for term, value in zip(source.terms, source.term_values()):
        if term.rate:
            continue
        if term.kind in (STORED, DISSIPATED):
            total += value
        elif term.kind == WORK:
            total -= value
        if term.name == "contact_area_work":
            area = value
    return total, area


class Closure:
    """Work of each source's forces on the blank, accumulated cycle by cycle: the increment from the last positions
    to the new ones pairs the forces evaluated at both (the trapezoidal rule of the engine's central differences)."""

    def __init__(self, problem):
        self.sources = list(problem.groups) + [e for e in problem.effects if e.forces is not None]
        # the sign that makes a source's contribution the force ON the nodes ("internal": resisting forces)
        self.sign = [-1.0 if getattr(s, "forces", "internal") == "internal" else 1.0 for s in self.sources]
        self.work = np.zeros(len(self.sources))
        self.force: dict[int, np.ndarray] = {}  # each source's force at the last positions
        self.x_last = None
        self.dx = None
        for i, s in enumerate(self.sources):
            name = "add_forces" if s in problem.groups else "add_force"
            setattr(s, name, self._wrap(i, getattr(s, name)))
        first = problem.groups[0]
        update = first.update

        def seen(x, v):  # every force evaluation starts here, at the new positions
            self.dx = None if self.x_last is None else x - self.x_last
            self.x_last = x.copy()
            return update(x, v)

        first.update = seen

    def _wrap(self, i, add):
        def wrapped(*args):
            target = args[-1]
            before = target.copy()
            add(*args)
            force = self.sign[i] * (target - before)
            if self.dx is not None and i in self.force:
                self.work[i] += 0.5 * float(((force + self.force[i]) * self.dx).sum())
            self.force[i] = force
        return wrapped

    def booked(self) -> tuple[np.ndarray, np.ndarray]:
        """Each source's (booked energy, contact_area_work) now [mJ] (``booked``)."""
        pairs = np.array([booked(s) for s in self.sources])
        return pairs[:, 0], pairs[:, 1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("deck", type=Path, nargs="?")
    ap.add_argument("--study", type=Path)
    ap.add_argument("--variant")
    ap.add_argument("--rows", type=int, default=12)
    a = ap.parse_args(argv)
    if a.deck is None and a.study is None:
        ap.error("give a DECK or --study with --variant")
    data, base = load(a.deck, a.study, a.variant)
    problem = compile_deck(Deck.model_validate(data), base)
    if any(getattr(e, "subcycles", False) for e in problem.effects):
        raise SystemExit("subcycled steps: their groups update at their own levels, which this probe does not follow")
    if problem.rotations is not None:
        raise SystemExit("shell nodes with rotations: the work of moments is not counted here")
    probe = Closure(problem)
    rated = [f"{s.name}: {t.name}" for s in probe.sources for t in s.terms if t.rate]
    if rated:
        print("left out (rates, integrated by the engine's ledger only; in these sources' closures):", ", ".join(rated))
    rows = []

    class Sink(solver.Sink):
        def history(self, row):
            rows.append((list(row), probe.work.copy(), *probe.booked()))

    result = solver.run(problem, Sink())
    print(f"status {result.status} {result.message or ''}, {result.cycles} cycles")
    err = result.columns.index("energy_balance_error")
    names = [getattr(s, "name", type(s).__name__) for s in probe.sources]
    print("time [s], balance error, then per source: closure (booked change + work of its forces on the blank) [mJ]; "
          "for a contact, in brackets, the closure without its booked contact_area_work")
    print(" " * 20 + " | ".join(f"{n[:26]:>26s}" for n in names))
    _, w0, b0, a0 = rows[0]
    shown = rows[::max(1, len(rows) // a.rows)]
    for row, w, b, aw in shown + ([] if shown[-1] is rows[-1] else [rows[-1]]):
        closure = (b - b0) + (w - w0)
        without = closure + (aw - a0)
        cells = [f"{c:+12.4f}" + (f" [{u:+11.4f}]" if u != c else " " * 14) for c, u in zip(closure, without)]
        print(f"{row[0]:8.4f} {row[err]:+10.4f} " + " | ".join(cells))
    return 0


if __name__ == "__main__":
    sys.exit(main())
