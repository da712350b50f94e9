"""Shared helpers for tests: build decks from dicts or files and run them in-process."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DECKS = ROOT / "decks"


def deck_data(name: str) -> dict:
    """The plain data of a deck in decks/ (through fdeck's own loader)."""
    from fdeck.deck.loader import load_file

    data, _ = load_file(DECKS / name)
    return copy.deepcopy(data)


def run_data(data: dict, base: Path = DECKS):
    """Validate, compile and run deck data; returns (problem, result, history dict of columns)."""
    from fdeck.compile.problem import compile_deck
    from fdeck.deck.model import Deck
    from fdeck.engine import solver

    deck = Deck.model_validate(data)
    problem = compile_deck(deck, base)
    result = solver.run(problem, solver.Sink())
    h = np.array(result.history)
    return problem, result, {c: h[:, i] for i, c in enumerate(result.columns)}


def merge(data: dict, **changes) -> dict:
    """Copy of data with top-level keys replaced."""
    out = copy.deepcopy(data)
    out.update(changes)
    return out
