"""Packed parameter layouts: a law names the blocks of its flat parameter vector once, in order, with their sizes.

``P = layout(lam=1, mu=1)`` gives ``P.lam == 0``, ``P.mu == 1`` and ``P.size == 2``: a namedtuple of plain ints, which
numba reads as compile-time constants in kernels (``params[P.mu]``), so ``pack``, the kernels and the diagnostics
share one declaration and an edited layout cannot leave a stale offset behind.
"""

from __future__ import annotations

from collections import namedtuple


def layout(**sizes: int):
    """Offsets of consecutive blocks of the given sizes (keyword order), plus ``size``, the total length."""
    offsets, at = {}, 0
    for name, n in sizes.items():
        if n < 1:
            raise ValueError(f"block {name!r} has size {n}")
        offsets[name] = at
        at += n
    return namedtuple("Layout", [*offsets, "size"])(*offsets.values(), at)
