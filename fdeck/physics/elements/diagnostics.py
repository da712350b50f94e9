"""Element output of a material's point diagnostics (shear angle, fibre strains, current fibre directions, ...):
the weighted mean over each element's points, in one compiled loop.

Why a compiled loop: called from Python once per point, a material's ``diagnose`` costs its dispatch (about 8 us)
per call; on the 24 000-hexahedron tetrahedron a `max_shear_angle` history measure took 1.6 s per row that way
(14 % of the run's first minutes at 500 history rows). Here one loop per material calls that material's jitted
``diagnose`` directly, compiled once per process and kept (``_loop``). Not in numba's on-disk cache: a cached loop
taking ``diagnose`` as a first-class function argument (the first version) keys its cache index on the
dispatcher's type, and a process that loaded an index another had just written could not write it back
("underlying object has vanished", seen on a cold cache in the test suite); compiling the loop costs a fraction of
a second, once, in the processes that write element output.

Parallel over elements from ``PARALLEL_POINTS`` points on: at 500 history rows the `max_shear_angle` measure was
5 % of the 5 mm `ans_tbar` tetrahedron's run (README, *Forming*); without the stress (``cell_fields``' ``names``)
and in parallel, 0.020 against 0.113 s per row on 2 threads. The parallel loop compiles in about 1.1 s against
0.3 s for the serial one (measured, 2 threads), which a small model's run would pay and never win back.
"""

from __future__ import annotations

import numba
import numpy as np

from fdeck.jit import FLAGS

_LOOPS: dict = {}  # (material diagnose, parallel) -> its compiled loop, for this process
# points (elements x points per element) from which a call runs the parallel loop: there the serial one takes
# 20 ms or more per call (0.19 us per point), so the parallel one's extra 0.8 s of compiling is won back within
# about a hundred calls (a large run's history rows), and a small model never compiles it
PARALLEL_POINTS = 100_000


def _loop(diagnose, parallel: bool):
    """The compiled loop vals[e] += w[e, q] diagnose(F[e, q], frame[src[e, q]], params[src[e, q]]) over every
    element e and point q, for one material's ``diagnose``, over the elements in parallel or not (each element
    its own row of vals: the same bits either way). F (n, k, 3, 3); frame (m, 3, 3); params (m, n_params); src,
    w (n, k); vals (n, n_diagnostics)."""
    loop = _LOOPS.get((diagnose, parallel))
    if loop is None:
        @numba.njit(**{**FLAGS, "cache": False, "parallel": parallel})
        def loop(F, frame, params, src, w, vals):
            for e in numba.prange(F.shape[0]):  # a plain range when not parallel
                for q in range(F.shape[1]):
                    d = diagnose(F[e, q], frame[src[e, q]], params[src[e, q]])
                    for i in range(vals.shape[1]):
                        vals[e, i] += w[e, q] * d[i]
        _LOOPS[(diagnose, parallel)] = loop
    return loop


def averaged(material, F: np.ndarray, frame: np.ndarray, params: np.ndarray, src: np.ndarray,
             w: np.ndarray) -> dict[str, np.ndarray]:
    """{diagnostic name: (n,) weighted mean over each element's k points}. F (n, k, 3, 3) the deformation gradients
    the material sees; frame (m, 3, 3) and params (m, n_params) the group's fibre frames and packed laws, of which
    point (e, q) uses row src[e, q] (src (n, k) int: a hexahedron's element, a shell's corner); w (n, k) weights
    summing to 1 per element. Empty when the material has no diagnostics."""
    if material.diagnose is None:
        return {}
    vals = np.zeros((F.shape[0], len(material.diagnostics)))
    loop = _loop(material.diagnose, F.shape[0] * F.shape[1] >= PARALLEL_POINTS)
    loop(np.ascontiguousarray(F), frame, params, np.ascontiguousarray(src, np.int64),
         np.ascontiguousarray(w, dtype=float), vals)
    return {name: vals[:, i] for i, name in enumerate(material.diagnostics)}
