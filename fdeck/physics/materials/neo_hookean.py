"""Compressible neo-Hookean law: psi = mu/2 (I1 - 3) - mu ln J + lam/2 (ln J)^2.

S = mu (I - C^-1) + lam ln J C^-1. Polyconvex and well defined for any J > 0; used to verify finite-strain
kinematics (F-bar, objectivity, compression) independently of the fabric laws.
"""

from typing import Literal

import numpy as np
from pydantic import Field

from fdeck.deck.base import MaterialCard
from fdeck.jit import njit, njit_parallel, prange
from fdeck.physics.tensor import inv3, sym_eig_max
from fdeck.registry import MaterialKind, register_material


class NeoHookean(MaterialCard):
    """Compressible neo-Hookean hyperelastic solid."""

    type: Literal["neo_hookean"]
    youngs_modulus: float = Field(gt=0.0, description="Small-strain Young's modulus E [MPa].")
    poisson_ratio: float = Field(gt=-1.0, lt=0.5, description="Small-strain Poisson ratio nu, -1 < nu < 0.5.")


def pack(card: NeoHookean) -> np.ndarray:
    """-> [lam, mu] small-strain Lame constants [MPa]."""
    e, nu = card.youngs_modulus, card.poisson_ratio
    return np.array([e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))])


@njit
def point(F, frame, params, state, P):
    """First Piola-Kirchhoff stress into P (3, 3); returns (psi [MPa], P-wave modulus [MPa])."""
    lam, mu = params[0], params[1]
    Finv = np.empty((3, 3))
    J = inv3(F, Finv)
    logJ = np.log(J)  # J <= 0 gives nan: the engine's monitor stops the run and names the element
    Finv_T = Finv.T
    # P = F S = mu (F - F^-T) + lam ln J F^-T
    P[:, :] = mu * (F - Finv_T) + lam * logJ * Finv_T
    psi = 0.5 * mu * (np.sum(F * F) - 3.0) - mu * logJ + 0.5 * lam * logJ * logJ
    # Reference acoustic tensor of A = dP/dF = mu I + (mu - lam ln J) F^-T(x)F^-1 + lam F^-T x F^-T is bounded by
    # mu + (|mu - lam ln J| + lam) / sigma_min(F)^2; exact (lam + 2 mu) at rest.
    return psi, mu + (abs(mu - lam * logJ) + lam) * sym_eig_max(Finv @ Finv_T)


@njit_parallel
def evaluate(F, frame, params, state, P, psi, modulus):
    """Array kernel; shapes in ``fdeck.registry.MaterialKind``."""
    for e in prange(F.shape[0]):
        for q in range(F.shape[1]):
            psi[e, q], modulus[e, q] = point(F[e, q], frame[e], params[e], state[e, q], P[e, q])


register_material(MaterialKind("neo_hookean", NeoHookean, pack, evaluate, point))
