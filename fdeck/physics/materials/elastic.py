"""Isotropic linear elastic law at finite strain (Saint Venant-Kirchhoff): S = lam tr(E) I + 2 mu E.

Linear in the Green-Lagrange strain E = (C - I)/2, hence objective under any rigid rotation and identical to Hooke's
law for small strains. Meant for verification decks (patch tests, waves, beams), not for large compression, where
Saint Venant-Kirchhoff softens.
"""


import numba
import numpy as np

from fdeck.jit import FLAGS, njit_parallel, prange
from fdeck.physics.layout import layout
from fdeck.physics.tensor import sym_bound6
from fdeck.registry import MaterialKind, register_material
from fdeck.cards.elastic import Isotropic






PARAMS = layout(lam=1, mu=1)
"""Packed parameters of the isotropic laws: the Lame constants lam, mu [MPa]."""


def pack(card: Isotropic) -> np.ndarray:
    """-> (PARAMS.size,) Lame constants [MPa] of any isotropic card."""
    e, nu = card.youngs_modulus, card.poisson_ratio
    p = np.empty(PARAMS.size)
    p[PARAMS.lam], p[PARAMS.mu] = e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))
    return p


@numba.njit(inline="always", **FLAGS)
def point(F, frame, params, state, P):
    """First Piola-Kirchhoff stress into P (3, 3); returns (psi [MPa], m1, m2, m3) with m_i the modulus
    bound [MPa] along each frame direction that sets the element step (isotropic: three equal values; see
    ``stress``).

    Written with scalars: no allocation per point (allocations dominate the cost of small kernels and contend
    between threads). Inlined at numba level into ``evaluate``: called as a function, each of its five array views
    cost an atomic reference-count increment and decrement per point (ten atomics on cache lines both threads
    share), and the call itself; inlined, numba prunes them (measured 129 -> 61 ns per point, same bits;
    docs/kernels.md).
    """
    p00, p01, p02, p10, p11, p12, p20, p21, p22, psi, m = stress(
        F[0, 0], F[0, 1], F[0, 2], F[1, 0], F[1, 1], F[1, 2], F[2, 0], F[2, 1], F[2, 2],
        params[PARAMS.lam], params[PARAMS.mu])
    P[0, 0], P[0, 1], P[0, 2] = p00, p01, p02
    P[1, 0], P[1, 1], P[1, 2] = p10, p11, p12
    P[2, 0], P[2, 1], P[2, 2] = p20, p21, p22
    return psi, m, m, m


@numba.njit(inline="always", **FLAGS)
def stress(f00, f01, f02, f10, f11, f12, f20, f21, f22, lam, mu):
    """The law at F given by its nine components (row-major): (P row-major, 9 values [MPa], psi [MPa], m [MPa]),
    m the modulus bound of every direction. Scalars in and out, so that both ``point`` and the block path of the
    one-point hexahedron (``hex8_blocks``, one element per SIMD lane) evaluate this one definition."""
    # Green-Lagrange strain E = (F^T F - I) / 2, symmetric: 6 components
    e00 = 0.5 * (f00 * f00 + f10 * f10 + f20 * f20 - 1.0)
    e11 = 0.5 * (f01 * f01 + f11 * f11 + f21 * f21 - 1.0)
    e22 = 0.5 * (f02 * f02 + f12 * f12 + f22 * f22 - 1.0)
    e01 = 0.5 * (f00 * f01 + f10 * f11 + f20 * f21)
    e12 = 0.5 * (f01 * f02 + f11 * f12 + f21 * f22)
    e02 = 0.5 * (f00 * f02 + f10 * f12 + f20 * f22)
    tr = e00 + e11 + e22
    s00, s11, s22 = lam * tr + 2.0 * mu * e00, lam * tr + 2.0 * mu * e11, lam * tr + 2.0 * mu * e22
    s01, s12, s02 = 2.0 * mu * e01, 2.0 * mu * e12, 2.0 * mu * e02
    psi = 0.5 * lam * tr * tr + mu * (e00 * e00 + e11 * e11 + e22 * e22 + 2.0 * (e01 * e01 + e12 * e12 + e02 * e02))
    # Reference acoustic tensor A = dP/dF: delta_ik S_JL + F_iI C_IJKL F_kK, bounded by
    # max eig(S) + (lam + 2 mu) max eig(F^T F) (eigenvalues bounded by Gershgorin), plus 2 lam: the Poisson coupling
    # of the three directions. The P-wave modulus lam + 2 mu bounds waves in a continuum, but a hexahedron with
    # lumped mass and free faces (one element through a section) has a dilatation mode stiffer by
    # (3 lam + 2 mu) / (lam + 2 mu): 1.86x at nu = 0.3, and central differences grew unstable at dt_safety 0.9
    # (found by the deck fuzzer: a 10 x 1 x 1 bar inverted in 50 cycles). With it the free element's step is exact
    # (tests/test_stable_step.py). Rest value 3 lam + 2 mu = 3 K.
    c_max = 1.0 + 2.0 * sym_bound6(e00, e11, e22, e01, e12, e02)
    m = max(0.0, sym_bound6(s00, s11, s22, s01, s12, s02)) + (3.0 * lam + 2.0 * mu) * c_max
    return (f00 * s00 + f01 * s01 + f02 * s02, f00 * s01 + f01 * s11 + f02 * s12, f00 * s02 + f01 * s12 + f02 * s22,
            f10 * s00 + f11 * s01 + f12 * s02, f10 * s01 + f11 * s11 + f12 * s12, f10 * s02 + f11 * s12 + f12 * s22,
            f20 * s00 + f21 * s01 + f22 * s02, f20 * s01 + f21 * s11 + f22 * s12, f20 * s02 + f21 * s12 + f22 * s22,
            psi, m)


@njit_parallel
def evaluate(F, frame, params, state, P, psi, modulus):
    """Array kernel; shapes in ``fdeck.registry.MaterialKind``."""
    for e in prange(F.shape[0]):
        for q in range(F.shape[1]):
            psi[e, q], modulus[e, q, 0], modulus[e, q, 1], modulus[e, q, 2] = point(
                F[e, q], frame[e], params[e], state[e, q], P[e, q])


register_material(MaterialKind("linear_elastic", pack, evaluate, point))
