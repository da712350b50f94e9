"""Amplitude curves a(t) as plain callables (evaluated once per cycle per effect)."""

from __future__ import annotations

from fdeck.deck.model import smoothstep


def make(name: str, cards: dict, total: float):
    """Callable a(t) for a built-in name (constant, ramp, smooth over [0, total]) or a deck amplitude card."""
    builtin = {
        "constant": lambda t: 1.0,
        "ramp": lambda t: min(1.0, max(0.0, t / total)),
        "smooth": lambda t: smoothstep(t / total),
    }
    return builtin[name] if name in builtin else cards[name].curve()
