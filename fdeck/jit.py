"""The one place that sets numba flags for every kernel in fdeck.

``cache=True`` keeps start-up short after the first run; ``error_model="numpy"`` lets a division by zero give
inf/nan (caught by the engine's monitors) instead of raising inside a parallel loop; ``fastmath`` stays off so
results are bitwise reproducible and regression tolerances stay meaningful.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numba


def _source_digest(root: Path | None = None) -> str:
    """SHA-256 (first 16 hex digits) of every source file of the package at ``root`` (fdeck's), in path order."""
    root = Path(__file__).resolve().parent if root is None else root
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def _cache_dir() -> str:
    """Where numba keeps fdeck's compiled kernels: one folder per state of the whole source tree.

    numba invalidates a cached kernel when the file that defines it changes, not when a function it calls from
    another file does, so a changed material or helper could run as its old compiled code (measured: a forming deck
    gave kinetic/internal 0.049 on such a cache, 0.096 freshly compiled). Keying the folder on a digest of every
    source file recompiles everything after any change (an upgrade, an edit) and never mixes versions. A user's
    ``NUMBA_CACHE_DIR`` wins. Old folders are not pruned: delete ``~/.cache/fdeck/numba`` to reclaim the space.
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return os.environ["NUMBA_CACHE_DIR"]
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return str(base / "fdeck" / "numba" / BUILD)


BUILD = _source_digest()
"""Digest of the source files this process imported (read once): keys the kernel cache and tags checkpoints."""

numba.config.CACHE_DIR = _cache_dir()

FLAGS = dict(cache=True, error_model="numpy", fastmath=False, nogil=True)

njit = numba.njit(**FLAGS)
"""Decorator for serial kernels and point functions."""

njit_parallel = numba.njit(parallel=True, **FLAGS)
"""Decorator for kernels whose outer loop is ``numba.prange`` over entities (elements or nodes)."""

njit_inline = numba.njit(inline="always", **FLAGS)
"""Decorator for small helpers called per element or node from a ``prange`` body: called as functions, every array
they take (and every view such as ``F[e, q]``) costs an atomic reference-count increment and decrement per call on
a counter all threads share; inlined at numba level, numba prunes them (docs/kernels.md)."""

prange = numba.prange
