"""Element output of the materials' point diagnostics (`physics/elements/diagnostics.py`): the compiled weighted
mean equals its definition, the material's `diagnose` called point by point from Python (what the hexahedra and
shells did before, at about 8 us of dispatch per call)."""

from __future__ import annotations

import numpy as np
import pytest

import fdeck.physics  # noqa: F401  (registers plug-ins)
from fdeck.physics.elements.diagnostics import _loop, averaged
from fdeck.registry import CARDS, MATERIALS


def rotations(rng, n):
    q, _ = np.linalg.qr(rng.standard_normal((n, 3, 3)))
    return q * np.sign(np.linalg.det(q))[:, None, None]


@pytest.mark.unit
@pytest.mark.parametrize("kind, card, k", [("fabric_hyper", {"type": "fabric_hyper", "preset": "3weave"}, 8),
                                           ("fabric_membrane", {"type": "fabric_membrane", "preset": "t300_3k"}, 12)])
def test_averaged_diagnostics_equal_the_point_by_point_mean(kind, card, k):
    """Requirement: for n elements of k points (8: a hexahedron; 12: a shell's 4 corners x 3 levels) with random
    deformations (F = I + 0.05 noise), each point reading a random row of the frames and laws (as a shell's
    corners or a hexahedron's elements do), random weights summing to 1, every diagnostic equals sum_q w_q diagnose(F_q, frame_q, params_q) evaluated in Python in the same order: bitwise
    (the same floating operations in the same order; no fastmath contraction), by the serial loop that small
    models use and by the parallel one of large models."""
    rng = np.random.default_rng(7)
    material = MATERIALS[kind]
    p = material.pack(CARDS["material"][kind].card(**card))
    n = 6
    F = np.eye(3) + 0.05 * rng.standard_normal((n, k, 3, 3))
    frame = rotations(rng, 2 * n)  # rows the points pick from, as a shell's corners or a hexahedron's elements
    params = np.tile(p, (2 * n, 1))  # contiguous rows: the signature the material tests compile too
    src = rng.integers(0, 2 * n, (n, k))
    w = rng.random((n, k))
    w /= w.sum(axis=1, keepdims=True)
    out = averaged(material, F, frame, params, src, w)
    expected = np.zeros((n, len(material.diagnostics)))
    for e in range(n):
        for q in range(k):
            expected[e] += w[e, q] * material.diagnose(F[e, q], frame[src[e, q]], params[src[e, q]])
    assert list(out) == list(material.diagnostics)
    for i, name in enumerate(material.diagnostics):
        assert np.array_equal(out[name], expected[:, i]), name
    assert np.abs(out["shear_angle"]).max() > 0.1  # the deformations shear: the comparison is not of zeros
    # the parallel loop (models of PARALLEL_POINTS points or more) gives the same bits: one row per element
    par = np.zeros_like(expected)
    _loop(material.diagnose, True)(F, frame, params, np.ascontiguousarray(src, np.int64), w, par)
    assert np.array_equal(par, expected)
