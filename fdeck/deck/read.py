"""Read a deck file: YAML with locations -> validated Deck, every problem located as file:line:col."""

from __future__ import annotations

from pathlib import Path

from pydantic import ValidationError

from fdeck.deck.errors import DeckError, Problem, format_path, problems_from_validation_error
from fdeck.deck.loader import Locations, load_file


def located(filename: str, locs: Locations | None, path: tuple, message: str, severity: str = "error") -> Problem:
    """A Problem at the deck position of ``path`` (its deepest existing ancestor)."""
    pos = locs.lookup(path) if locs is not None else None
    line, col = pos if pos else (None, None)
    return Problem(filename, line, col, format_path(path), message, severity)


def read_deck(path: str | Path):
    """-> (Deck, Locations, warnings). Raises DeckError listing every error (schema and name references)."""
    from fdeck.deck.model import Deck, cross_reference_problems

    path = Path(path)
    data, locs = load_file(path)
    try:
        deck = Deck.model_validate(data)
    except ValidationError as exc:
        raise DeckError(problems_from_validation_error(exc, locs, str(path), Deck)) from None
    found = [located(str(path), locs, p, m, sev) for p, m, sev in cross_reference_problems(deck)]
    if any(p.severity == "error" for p in found):
        raise DeckError(found)
    return deck, locs, found
