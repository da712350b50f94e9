"""The ``output.checkpoint`` card: how often the whole state of a run is saved for ``fdeck run --restart``."""

from __future__ import annotations

import math
import re

from pydantic import Field, field_validator

from fdeck.deck.base import Card

_WALL = re.compile(r"^\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(s|min|h)\s*$")
_CYCLES = re.compile(r"^\s*([0-9]+)\s*cycles?\s*$")
_SECONDS = {"s": 1.0, "min": 60.0, "h": 3600.0}


class Checkpoint(Card):
    """Save the whole state (positions, velocities, rotations, history variables, ledger, step plan position,
    history rows, frames written) every so often, atomically, in ``checkpoint_<cycle>.fdck`` of the output folder.
    A run also saves one when it completes and when it is stopped (SIGINT, SIGTERM, ``--max-wall``)."""

    every: int | str = Field(description="Interval: cycles as an integer (5000, or '5000 cycles') or wall time "
                             "with a unit ('30 s', '10 min', '1 h').")
    keep: int = Field(2, ge=1, description="Checkpoints kept in the output folder (the newest).")

    @field_validator("every", mode="before")
    @classmethod
    def _interval(cls, value):
        if isinstance(value, bool) or not isinstance(value, (int, str)):
            raise ValueError(f"{value!r} is not an interval: give cycles as an integer (every: 5000) or wall time "
                             "with a unit ('30 s', '10 min', '1 h')")
        if isinstance(value, int):
            if value < 1:
                raise ValueError(f"every {value} cycles: give at least 1 cycle")
            return value
        m = _CYCLES.match(value)
        if m:
            if int(m.group(1)) < 1:
                raise ValueError(f"every {value!r}: give at least 1 cycle")
            return int(m.group(1))
        m = _WALL.match(value)
        if not m:
            raise ValueError(f"{value!r} is not an interval: give cycles as an integer (every: 5000) or wall time "
                             "with a unit ('30 s', '10 min', '1 h')")
        seconds = float(m.group(1)) * _SECONDS[m.group(2)]
        if not (math.isfinite(seconds) and seconds > 0):
            raise ValueError(f"every {value!r}: the wall time must be positive and finite")
        return value.strip()

    @property
    def cycles(self) -> int | None:
        """The interval in cycles, or None when it is a wall time."""
        return self.every if isinstance(self.every, int) else None

    @property
    def seconds(self) -> float | None:
        """The interval in seconds of wall time, or None when it is in cycles."""
        if isinstance(self.every, int):
            return None
        m = _WALL.match(self.every)
        return float(m.group(1)) * _SECONDS[m.group(2)]
