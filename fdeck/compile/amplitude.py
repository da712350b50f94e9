"""Amplitude curves a(t) as plain callables (evaluated once per cycle per effect)."""

from __future__ import annotations

import numpy as np


def smoothstep(tau: float) -> float:
    """Quintic 0 -> 1 on [0, 1] with zero first and second derivatives at both ends."""
    s = min(1.0, max(0.0, tau))
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def make(name: str, cards: dict, total: float):
    """Callable a(t) for a built-in name (constant, ramp, smooth over [0, total]) or a deck card."""
    if name == "constant":
        return lambda t: 1.0
    if name == "ramp":
        return lambda t: min(1.0, max(0.0, t / total))
    if name == "smooth":
        return lambda t: smoothstep(t / total)
    card = cards[name]
    if card.type == "tabular":
        ts, vs = np.array([p[0] for p in card.points]), np.array([p[1] for p in card.points])
        return lambda t: float(np.interp(t, ts, vs))
    t0, t1, a0, a1 = card.t0, card.t1, card.a0, card.a1
    return lambda t: a0 + (a1 - a0) * smoothstep((t - t0) / (t1 - t0))
