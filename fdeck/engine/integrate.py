"""Node kernels of the central-difference update, fused so one cycle makes two passes over the nodes.

Shapes: every nodal array is (n_node, 3) [mm, mm/s, N]; m and inv_m are (n_node,) [t, 1/t].
"""

import numpy as np

from fdeck.jit import njit_inline, njit_parallel, prange


@njit_parallel
def kick(v, v_old, inv_m, f_ext, f_int, f_damp, dt_avg):
    """v_old = v; v += dt_avg (f_ext - f_int + f_damp) / m: the free update, before prescribed velocities."""
    for n in prange(v.shape[0]):
        for i in range(3):
            v_old[n, i] = v[n, i]
            v[n, i] += dt_avg * inv_m[n] * (f_ext[n, i] - f_int[n, i] + f_damp[n, i])


CHUNK = 256
"""Nodes per partial sum of the ledger increments: fixed, so that the sums do not depend on the thread count (a
prange reduction splits the nodes by thread, and its rounding with it)."""


@njit_inline
def chunk_totals(part):
    """The three columns of part (n_chunk, 3) summed serially, in chunk order."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for c in range(part.shape[0]):
        s0 += part[c, 0]
        s1 += part[c, 1]
        s2 += part[c, 2]
    return s0, s1, s2


@njit_parallel
def drift(x, v, v_old, m, f_ext, f_int, f_damp, fe_prev, fd_prev, dx, reaction, dt, dt_avg, first):
    """After prescribed velocities are set: reactions, ledger increments at t_n, then x += dt v.

    reaction = m (v - v_old) / dt_avg - (f_ext - f_int + f_damp): what the constraints added.
    Returns (external work increment over the previous step, damping dissipation increment, kinetic energy at
    t_n) by the trapezoidal rule on the previous increment dx, with v(t_n) = (v_old + v) / 2 (v_old itself on
    the first cycle, where v_old is the initial velocity), each summed per CHUNK nodes and then serially. Then
    fe_prev = f_ext + reaction, fd_prev = f_damp, dx = dt v, x += dx.
    """
    n_node = x.shape[0]
    part = np.zeros(((n_node + CHUNK - 1) // CHUNK, 3))
    for c in prange(part.shape[0]):
        w = 0.0
        d = 0.0
        ke = 0.0
        for n in range(c * CHUNK, min(n_node, (c + 1) * CHUNK)):
            for i in range(3):
                r = m[n] * (v[n, i] - v_old[n, i]) / dt_avg - (f_ext[n, i] - f_int[n, i] + f_damp[n, i])
                reaction[n, i] = r
                fe = f_ext[n, i] + r
                w += 0.5 * (fe_prev[n, i] + fe) * dx[n, i]
                d -= 0.5 * (fd_prev[n, i] + f_damp[n, i]) * dx[n, i]
                vn = v_old[n, i] if first else 0.5 * (v_old[n, i] + v[n, i])
                ke += 0.5 * m[n] * vn * vn
                fe_prev[n, i] = fe
                fd_prev[n, i] = f_damp[n, i]
                dx[n, i] = dt * v[n, i]
                x[n, i] += dx[n, i]
        part[c, 0] = w
        part[c, 1] = d
        part[c, 2] = ke
    return chunk_totals(part)
