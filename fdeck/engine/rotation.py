"""Rotational degrees of freedom: nodal directors and angular velocities, present only when a group needs them.

A node of a shell carries a unit director d (the current fibre-thickness direction) and an angular velocity w
[rad/s]. Groups return director forces g = dW/dd [N mm per unit of d]; the nodal moment is m = d x g, exactly
energy-consistent: for a rotation dtheta, dd = dtheta x d and dW = g . (dtheta x d) = dtheta . (d x g).

Central differences, with a lumped scalar rotational inertia I per node [t mm^2] (isotropic, so Euler's equations
have no gyroscopic term and w is the same in the spatial and the body frame):

    w(n+1/2) = w(n-1/2) + dt_avg (m_ext - m_int + m_damp) / I        (then prescribed rotations are imposed)
    d(n+1)   = R(dt w(n+1/2)) d(n)                                   (Rodrigues: an exact rotation, |d| stays 1)

A rotation about d itself (drilling) moves nothing and meets no stiffness: it is carried along, and since the
internal moment d x g is always normal to d it is never driven by the elements. Rodrigues' rotation about w keeps
w . d unchanged, so a w that starts normal to d stays normal to it unless a boundary condition says otherwise.

Ledger: kinetic energy 1/2 I |w(n)|^2 with w(n) = (w(n-1/2) + w(n+1/2)) / 2; the work of external and reaction
moments and the dissipation of damping moments by the trapezoidal rule on the rotation increment dt w(n+1/2)
(the exact rotation vector of the step). Arrays cover every node; nodes without a director have I = 0 and d = 0.
"""

from __future__ import annotations

import math

import numpy as np

from fdeck.engine.integrate import CHUNK, chunk_totals
from fdeck.jit import njit_parallel, prange


class Rotations:
    """Rotational state of a run. Shapes: (n_node, 3) unless stated; I, inv_I (n_node,).

    Objects that act on rotations (groups and effects with ``rotational = True``) are given this object once per run
    through their ``bind(rotations)``; in the force pass they add into ``m_int`` (groups, resisting sign), ``m_ext``
    (loads) or ``m_damp`` (damping), and constraints overwrite ``w`` at the half step.
    """

    def __init__(self, d0: np.ndarray, nodes: np.ndarray):
        n = len(d0)
        self.nodes = nodes  # indices of the nodes that carry a director
        self.d = d0.copy()
        self.w = np.zeros((n, 3))
        self.w_old = np.zeros((n, 3))
        self.m_int = np.zeros((n, 3))
        self.m_ext = np.zeros((n, 3))
        self.m_damp = np.zeros((n, 3))
        self.me_prev = np.zeros((n, 3))
        self.md_prev = np.zeros((n, 3))
        self.dtheta = np.zeros((n, 3))
        self.reaction = np.zeros((n, 3))
        self.I = np.zeros(n)
        self.inv_I = np.zeros(n)

    def set_inertia(self, inertia: np.ndarray) -> None:
        self.I[:] = inertia
        self.inv_I[:] = np.where(inertia > 0.0, 1.0 / np.where(inertia > 0.0, inertia, 1.0), 0.0)

    def clear(self) -> None:
        self.m_int.fill(0.0)
        self.m_ext.fill(0.0)
        self.m_damp.fill(0.0)


@njit_parallel
def kick_rot(w, w_old, inv_I, m_ext, m_int, m_damp, dt_avg):
    """w_old = w; w += dt_avg (m_ext - m_int + m_damp) / I (zero change where I = 0)."""
    for n in prange(w.shape[0]):
        for i in range(3):
            w_old[n, i] = w[n, i]
            w[n, i] += dt_avg * inv_I[n] * (m_ext[n, i] - m_int[n, i] + m_damp[n, i])


@njit_parallel
def drift_rot(d, w, w_old, I, m_ext, m_int, m_damp, me_prev, md_prev, dtheta, reaction, dt, dt_avg, first):
    """After prescribed rotations are set: reaction moments, ledger increments at t_n, then d = R(dt w) d.

    reaction = I (w - w_old) / dt_avg - (m_ext - m_int + m_damp). Returns (work of external + reaction moments over
    the previous step, damping dissipation, rotational kinetic energy at t_n), as ``integrate.drift`` does for
    forces (summed per ``integrate.CHUNK`` nodes, then serially). Then me_prev = m_ext + reaction, md_prev = m_damp,
    dtheta = dt w and every director is rotated by Rodrigues' formula R(a) d = d cos|a| + (a^ x d) sin|a| +
    a^ (a^ . d)(1 - cos|a|), a^ = a / |a|.
    """
    n_node = d.shape[0]
    part = np.zeros(((n_node + CHUNK - 1) // CHUNK, 3))
    for k in prange(part.shape[0]):
        work = 0.0
        diss = 0.0
        ke = 0.0
        for n in range(k * CHUNK, min(n_node, (k + 1) * CHUNK)):
            for i in range(3):
                r = I[n] * (w[n, i] - w_old[n, i]) / dt_avg - (m_ext[n, i] - m_int[n, i] + m_damp[n, i])
                reaction[n, i] = r
                me = m_ext[n, i] + r
                work += 0.5 * (me_prev[n, i] + me) * dtheta[n, i]
                diss -= 0.5 * (md_prev[n, i] + m_damp[n, i]) * dtheta[n, i]
                wn = w_old[n, i] if first else 0.5 * (w_old[n, i] + w[n, i])
                ke += 0.5 * I[n] * wn * wn
                me_prev[n, i] = me
                md_prev[n, i] = m_damp[n, i]
                dtheta[n, i] = dt * w[n, i]
            a0, a1, a2 = dtheta[n, 0], dtheta[n, 1], dtheta[n, 2]
            angle = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
            if angle > 0.0:
                u0, u1, u2 = a0 / angle, a1 / angle, a2 / angle
                d0, d1, d2 = d[n, 0], d[n, 1], d[n, 2]
                c, s = math.cos(angle), math.sin(angle)
                ud = (u0 * d0 + u1 * d1 + u2 * d2) * (1.0 - c)
                d[n, 0] = d0 * c + (u1 * d2 - u2 * d1) * s + u0 * ud
                d[n, 1] = d1 * c + (u2 * d0 - u0 * d2) * s + u1 * ud
                d[n, 2] = d2 * c + (u0 * d1 - u1 * d0) * s + u2 * ud
        part[k, 0] = work
        part[k, 1] = diss
        part[k, 2] = ke
    return chunk_totals(part)
