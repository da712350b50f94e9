"""Every deck in decks/ validates, compiles and runs a few cycles with finite energies."""

from __future__ import annotations

import math

import pytest

from helpers import DECKS

pytestmark = pytest.mark.smoke
ALL = (sorted(DECKS.glob("*.yaml")) + sorted(DECKS.glob("three_point_bending/*.yaml"))
       + sorted(DECKS.glob("coupons/*.yaml")))


@pytest.mark.parametrize("path", ALL, ids=[p.stem for p in ALL])
def test_deck_runs_a_few_cycles(path):
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.read import read_deck
    from fdeck.engine import solver

    deck, _, _ = read_deck(path)
    steps = [s.model_copy(update={"max_cycles": 5}) for s in deck.steps]
    deck = deck.model_copy(update={"steps": steps})
    problem = compile_deck(deck, path.parent)
    result = solver.run(problem, solver.Sink())
    assert result.status == "completed" and result.cycles >= 5
    assert all(math.isfinite(v) for row in result.history for v in row)
