"""Closed-form 3x3 helpers for kernels (faster than LAPACK calls on 3x3 blocks)."""

import math

import numba

from fdeck.jit import FLAGS, njit


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
def sym_eig_max6(a00, a11, a22, a01, a12, a02):
    """Largest eigenvalue of the symmetric matrix with the given components (trigonometric closed form;
    Smith, Comm. ACM 4 (1961) 168). No allocation: usable in hot kernels."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    if p1 <= 1e-30 * (q * q + 1e-300):
        return max(a00, a11, a22)
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1) / 6.0)
    det = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02))
    r = min(1.0, max(-1.0, 0.5 * det / (p * p * p)))
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0)


@njit
def sym_eig_max(A):
    """Largest eigenvalue of a symmetric (3, 3) array."""
    return sym_eig_max6(A[0, 0], A[1, 1], A[2, 2], A[0, 1], A[1, 2], A[0, 2])


@njit
def sym_bound6(a00, a11, a22, a01, a12, a02):
    """Gershgorin upper bound of the largest eigenvalue of a symmetric matrix: max_i (a_ii + sum_j |a_ij|).

    Exact for diagonal matrices (the rest state) and within the off-diagonal magnitudes otherwise; used for
    stable-step moduli, where an upper bound is what is needed and transcendental functions cost too much.
    """
    return max(a00 + abs(a01) + abs(a02), a11 + abs(a01) + abs(a12), a22 + abs(a02) + abs(a12))


@numba.njit(inline="always", **FLAGS)
def push(F, frame, i):
    """a_i = F f_i as 3 scalars: current image of reference direction i (row i of frame (3, 3)) under F (3, 3).
    Inlined at numba level into the fabric laws' point kernels."""
    f0, f1, f2 = frame[i, 0], frame[i, 1], frame[i, 2]
    return (F[0, 0] * f0 + F[0, 1] * f1 + F[0, 2] * f2,
            F[1, 0] * f0 + F[1, 1] * f1 + F[1, 2] * f2,
            F[2, 0] * f0 + F[2, 1] * f1 + F[2, 2] * f2)
