"""The one place that sets numba flags for every kernel in fdeck.

``cache=True`` keeps start-up short after the first run; ``error_model="numpy"`` lets a division by zero give
inf/nan (caught by the engine's monitors) instead of raising inside a parallel loop; ``fastmath`` stays off so
results are bitwise reproducible and regression tolerances stay meaningful.
"""

import numba

FLAGS = dict(cache=True, error_model="numpy", fastmath=False, nogil=True)

njit = numba.njit(**FLAGS)
"""Decorator for serial kernels and point functions."""

njit_parallel = numba.njit(parallel=True, **FLAGS)
"""Decorator for kernels whose outer loop is ``numba.prange`` over entities (elements or nodes)."""

prange = numba.prange
