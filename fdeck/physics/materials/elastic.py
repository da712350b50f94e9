"""Isotropic linear elastic law at finite strain (Saint Venant-Kirchhoff): S = lam tr(E) I + 2 mu E.

Linear in the Green-Lagrange strain E = (C - I)/2, hence objective under any rigid rotation and identical to Hooke's
law for small strains. Meant for verification decks (patch tests, waves, beams), not for large compression, where
Saint Venant-Kirchhoff softens.
"""

from typing import Literal

import numpy as np
from pydantic import Field

from fdeck.deck.base import MaterialCard
from fdeck.jit import njit, njit_parallel, prange
from fdeck.physics.tensor import sym_eig_max
from fdeck.registry import MaterialKind, register_material


class LinearElastic(MaterialCard):
    """Isotropic linear elastic (Saint Venant-Kirchhoff at finite strain)."""

    type: Literal["linear_elastic"]
    youngs_modulus: float = Field(gt=0.0, description="Young's modulus E [MPa].")
    poisson_ratio: float = Field(gt=-1.0, lt=0.5, description="Poisson ratio nu, -1 < nu < 0.5.")


def pack(card: LinearElastic) -> np.ndarray:
    """-> [lam, mu] Lame constants [MPa]."""
    e, nu = card.youngs_modulus, card.poisson_ratio
    return np.array([e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))])


@njit
def point(F, frame, params, state, P):
    """First Piola-Kirchhoff stress into P (3, 3); returns (psi [MPa], P-wave modulus [MPa])."""
    lam, mu = params[0], params[1]
    E = 0.5 * (F.T @ F - np.eye(3))
    trE = E[0, 0] + E[1, 1] + E[2, 2]
    S = 2.0 * mu * E
    for i in range(3):
        S[i, i] += lam * trE
    P[:, :] = F @ S
    psi = 0.5 * lam * trE * trE + mu * np.sum(E * E)
    # Reference acoustic tensor A = dP/dF: delta_ik S_JL + F_iI C_IJKL F_kK, bounded by
    # max eig(S) + (lam + 2 mu) max eig(F^T F); exact (lam + 2 mu) at rest.
    return psi, max(0.0, sym_eig_max(S)) + (lam + 2.0 * mu) * sym_eig_max(F.T @ F)


@njit_parallel
def evaluate(F, frame, params, state, P, psi, modulus):
    """Array kernel; shapes in ``fdeck.registry.MaterialKind``."""
    for e in prange(F.shape[0]):
        for q in range(F.shape[1]):
            psi[e, q], modulus[e, q] = point(F[e, q], frame[e], params[e], state[e, q], P[e, q])


register_material(MaterialKind("linear_elastic", LinearElastic, pack, evaluate, point))
