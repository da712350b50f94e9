"""Closed-form 3x3 helpers for kernels (faster than LAPACK calls on 3x3 blocks)."""

import math

import numpy as np

from fdeck.jit import njit


@njit
def det3(A):
    """Determinant of a (3, 3) array."""
    return (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))


@njit
def inv3(A, out):
    """Inverse of A (3, 3) into out (3, 3); returns det A (out is inf/nan when det A = 0)."""
    d = det3(A)
    r = 1.0 / d
    out[0, 0] = (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]) * r
    out[0, 1] = (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) * r
    out[0, 2] = (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) * r
    out[1, 0] = (A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]) * r
    out[1, 1] = (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) * r
    out[1, 2] = (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) * r
    out[2, 0] = (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]) * r
    out[2, 1] = (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) * r
    out[2, 2] = (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) * r
    return d


@njit
def sym_eig_max(A):
    """Largest eigenvalue of a symmetric (3, 3) array (trigonometric closed form)."""
    p1 = A[0, 1] ** 2 + A[0, 2] ** 2 + A[1, 2] ** 2
    q = (A[0, 0] + A[1, 1] + A[2, 2]) / 3.0
    if p1 <= 1e-30 * (q * q + 1e-300):
        return max(A[0, 0], A[1, 1], A[2, 2])
    p2 = (A[0, 0] - q) ** 2 + (A[1, 1] - q) ** 2 + (A[2, 2] - q) ** 2 + 2.0 * p1
    p = math.sqrt(p2 / 6.0)
    B = (A - q * np.eye(3)) / p
    r = min(1.0, max(-1.0, 0.5 * det3(B)))
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0)
