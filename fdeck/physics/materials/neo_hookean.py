"""Compressible neo-Hookean law: psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2.

S = mu (I - C^-1) + lam ln J C^-1. Polyconvex and well defined for any J > 0; used to verify finite-strain
kinematics (F-bar, objectivity, compression) independently of the fabric laws.
"""


import numpy as np

from fdeck.jit import njit, njit_parallel, prange
from fdeck.physics.materials.elastic import PARAMS, pack
from fdeck.physics.tensor import sym_bound6
from fdeck.registry import MaterialKind, register_material




@njit
def point(F, frame, params, state, P):
    """First Piola-Kirchhoff stress into P (3, 3); returns (psi [MPa], m1, m2, m3) with m_i the modulus
    bound [MPa] along each frame direction that sets the element step (isotropic: three equal values).

    P = mu F + (lam ln J - mu) F^-T, with F^-T = cof(F) / J built in place in P (no allocation per point).
    """
    lam, mu = params[PARAMS.lam], params[PARAMS.mu]
    # cofactor matrix of F, written into P
    P[0, 0] = F[1, 1] * F[2, 2] - F[1, 2] * F[2, 1]
    P[0, 1] = F[1, 2] * F[2, 0] - F[1, 0] * F[2, 2]
    P[0, 2] = F[1, 0] * F[2, 1] - F[1, 1] * F[2, 0]
    P[1, 0] = F[0, 2] * F[2, 1] - F[0, 1] * F[2, 2]
    P[1, 1] = F[0, 0] * F[2, 2] - F[0, 2] * F[2, 0]
    P[1, 2] = F[0, 1] * F[2, 0] - F[0, 0] * F[2, 1]
    P[2, 0] = F[0, 1] * F[1, 2] - F[0, 2] * F[1, 1]
    P[2, 1] = F[0, 2] * F[1, 0] - F[0, 0] * F[1, 2]
    P[2, 2] = F[0, 0] * F[1, 1] - F[0, 1] * F[1, 0]
    J = F[0, 0] * P[0, 0] + F[0, 1] * P[0, 1] + F[0, 2] * P[0, 2]
    logJ = np.log(J)  # J <= 0 gives nan: the engine's monitor stops the run and names the element
    # C^-1 = F^-1 F^-T = cof^T cof / J^2: its largest eigenvalue is 1 / sigma_min(F)^2
    r2 = 1.0 / (J * J)
    b00 = (P[0, 0] ** 2 + P[1, 0] ** 2 + P[2, 0] ** 2) * r2
    b11 = (P[0, 1] ** 2 + P[1, 1] ** 2 + P[2, 1] ** 2) * r2
    b22 = (P[0, 2] ** 2 + P[1, 2] ** 2 + P[2, 2] ** 2) * r2
    b01 = (P[0, 0] * P[0, 1] + P[1, 0] * P[1, 1] + P[2, 0] * P[2, 1]) * r2
    b12 = (P[0, 1] * P[0, 2] + P[1, 1] * P[1, 2] + P[2, 1] * P[2, 2]) * r2
    b02 = (P[0, 0] * P[0, 2] + P[1, 0] * P[1, 2] + P[2, 0] * P[2, 2]) * r2
    c = (lam * logJ - mu) / J
    i1 = 0.0
    for i in range(3):
        for j in range(3):
            i1 += F[i, j] * F[i, j]
            P[i, j] = mu * F[i, j] + c * P[i, j]
    psi = 0.5 * mu * (i1 - 3.0) - mu * logJ + 0.5 * lam * logJ * logJ
    # Reference acoustic tensor of A = dP/dF = mu I + (mu - lam ln J) F^-T(x)F^-1 + lam F^-T x F^-T is bounded by
    # mu + (|mu - lam ln J| + lam) / sigma_min(F)^2; exact (lam + 2 mu) at rest. Plus 2 lam / sigma_min^2, the
    # Poisson coupling of a lumped-mass hexahedron's dilatation mode (see fdeck.physics.materials.elastic): 3 K at rest.
    m = mu + (abs(mu - lam * logJ) + 3.0 * lam) * sym_bound6(b00, b11, b22, b01, b12, b02)
    return psi, m, m, m


@njit_parallel
def evaluate(F, frame, params, state, P, psi, modulus):
    """Array kernel; shapes in ``fdeck.registry.MaterialKind``."""
    for e in prange(F.shape[0]):
        for q in range(F.shape[1]):
            psi[e, q], modulus[e, q, 0], modulus[e, q, 1], modulus[e, q, 2] = point(
                F[e, q], frame[e], params[e], state[e, q], P[e, q])


register_material(MaterialKind("neo_hookean", pack, evaluate, point))
