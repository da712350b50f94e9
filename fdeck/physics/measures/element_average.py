"""Volume-weighted average of an element output field over an element set (e.g. the central shear angle)."""

from __future__ import annotations


import numpy as np

from fdeck.compile.errors import CompileError
from fdeck.registry import MeasureKind, register_measure




class Measure:
    """Evaluates the field on the selected elements only (each group's ``cell_fields(subset)``)."""

    def __init__(self, card, parts):
        self.columns = [card.name]
        self.card, self.parts = card, parts  # [(group, local element indices, weights)]

    def evaluate(self, x, v):
        vals, wts = [], []
        for g, idx, w in self.parts:
            vals.append(g.cell_fields(idx, (self.card.field,))[self.card.field])
            wts.append(w)
        vals, wts = np.concatenate(vals), np.concatenate(wts)
        if self.card.reduce == "mean":
            return [float(np.sum(vals * wts) / np.sum(wts))]
        return [float(getattr(np, self.card.reduce)(vals))]


def build(card, ctx):
    sets = ctx.mesh.element_sets
    if card.elements not in sets:
        raise CompileError([(ctx.path + ("elements",), f"unknown element set '{card.elements}'")])
    parts = []
    for g in ctx.groups:
        for ctype, idx in sets[card.elements].items():
            if ctype != g.cell_type:
                continue
            local = np.nonzero(np.isin(g.element_index, idx))[0]
            if len(local):
                parts.append((g, local, g.V0[local]))
    if not parts:
        raise CompileError([(ctx.path + ("elements",), f"set '{card.elements}' has no element in any section")])
    g0 = parts[0][0]
    available = g0.cell_fields(parts[0][1][:1]).keys()
    if card.field not in available:
        raise CompileError([(ctx.path + ("field",), f"unknown field '{card.field}' (available: "
                             f"{', '.join(sorted(available))})")])
    return Measure(card, parts)


register_measure(MeasureKind("element_average", build))
