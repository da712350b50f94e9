"""Selective mass scaling: a non-diagonal added mass on the deformation modes of each element, solved per cycle.

Method: Olovsson, Simonsson & Unosson, "Selective mass scaling for explicit finite element analyses", IJNME 63
(2005); the iterative solve as in Olovsson & Simonsson, "Iterative solution technique in selective mass scaling",
Comm. Numer. Meth. Engng 22 (2006). Per element e with n nodes, lumped element mass m_e [t] and factor beta_e:

    dM_e = beta_e (m_e / n) (I - P_e),   P_e the orthogonal projector on the element's 6 rigid modes (3n x 3n)

with the rigid modes (translations c, rotations w x dX_a) taken at the element's current positions
dX_a = x_a - mean(x), moved there every cycle (``follow``; below).

* ``dM_e`` vanishes on rigid motion: total mass, momentum (1^T (M + dM) v = sum m v), the response to a uniform
  acceleration (gravity) and the rotary inertia of a rigid turn are those of the lumped mass M.
* For an element whose lumped masses are equal (m_e / n: every parallelepiped), each deformation mode phi of
  (K_e, M_e) is orthogonal to the rigid modes (they span the null space of the symmetric K_e), so
  (M_e + dM_e) phi = (1 + beta_e) M_e phi: every nonzero element eigenvalue divides by 1 + beta_e and the element
  step grows by sqrt(1 + beta_e), as with a density rho (1 + beta_e); by the element eigenvalue bound the
  assembled step does too.
* A collapsed hexahedron (the prisms of ``mesh.block.lattice: diagonal``) repeats a node in two slots, so its
  lumped masses are not equal and that node takes two slots' share of dM_e: the step gain on a prism is below
  sqrt(1 + beta_e) (measured 2.06 against 2.15 at beta = 3.6, 3.7 % short), which the prism's conservative element
  step estimate (about 1.36x below its true step) covers; not corrected.
* Kinetic energy 1/2 v^T (M + dM) v, with 1/2 v^T dM_e v = 1/2 beta_e (m_e / n) |(I - P_e) v_e|^2 (booked in the
  engine's kinetic energy).

Why the current rigid modes. With the reference ones (fdeck until 2026-11-29) a turned or sheared element's
reference rotations are deformations of its current shape that carry the translational mass m_e / n alone: their
frequency rises towards sqrt(1 + beta_e) times what the element's step estimate allows, so the assembled critical
step falls below the scaled one as the blank turns: the 3 mm tetrahedron (tracking raised beta_e to 100-230 on
its flank) ran away there at 47-52 mm of stroke, and with the rigid modes following it forms to the end (README,
*Forming*; ``tests/test_selective_mass.py``: a turned strip's top eigenvalue 6.8x with the reference projectors,
unchanged to 2e-10 with the current ones). ``studies/critical_step.py`` measures a run's critical step at a
checkpoint.
Following costs two things. The mass changes with the configuration, so central differences no longer conserve
1/2 v^T (M + dM) v by themselves: what following changes at fixed velocities, 1/2 v^T (dM(x_n+1) - dM(x_n)) v at
the half-step velocities, is booked (``mass_corotation_work``; second order in the angle an element turns per
cycle, small for a spin: ``tests/test_selective_mass.py``). And one more element pass and one node pass per cycle
(rigid fit and preconditioner). Translations do not depend on the positions, so the momentum statements above hold
exactly; the projector on translations alone (I - 1 1^T / n, frame-indifferent, no update) would instead scale the
whole rotary inertia of every element, (L_e^2 + h_e^2) / 4 per unit mass with lumped nodes: on a slender strip with
5 mm elements and a 5x step that moves the first bending frequency by 1.7 %, the six-mode projector by less than
0.01 % (``tests/test_selective_mass.py``).

Per cycle the engine forms r = f_ext - f_int + f_damp, and the constraints fix the accelerations a_c of prescribed
dofs; the free accelerations solve (M + dM)_ff a_f = r_f - dM_fc a_c (with implicit contact springs K,
``engine.springs``: M + dM + dt dt_avg K, and r less dt K (v_old - v_tool)) by conjugate gradients preconditioned by
the diagonal, warm-started from the last cycles' a, with element-by-element products (no assembled matrix): each
element reduces p to seven numbers (``element_rows``) and each node sums its elements' in a fixed order (CSR node
-> slots, ``engine.gather.node_slots``); dot products are summed per fixed chunk of nodes and then serially, so
runs are bitwise identical on any thread count.

Shapes: nodal arrays (n_node, 3) [mm/s^2, N, mm/s]; m (n_node,) [t]; conn (n_el, 8) node indices (int32); c
(n_el,) = beta_e m_e / n [t]; free (n_node, 3) 1.0 on free dofs, 0.0 on prescribed ones.
"""

from __future__ import annotations

import numpy as np

from fdeck.engine import springs as sp
from fdeck.engine.gather import node_slots
from fdeck.jit import njit, njit_inline, njit_parallel, prange

WARM_START_ORDER = 2
"""Degree of the polynomial through the last cycles' accelerations that starts each solve (0: the last cycle's)."""

CHUNK = 256  # nodes per partial sum of a dot product (fixed, so the sums do not depend on the thread count)


NODES = 8  # hexahedra only (shells are refused): a constant trip count lets the compiler unroll the node loops

ROW = 8
"""Doubles per element in the product's rows: c_e, s_e (3), W_e (3) and one pad (``element_rows``): 64 bytes, a
cache line's size, though numpy aligns the array to 16 bytes only. Aligned to 64 it was no faster (measured with
``benchmarks/kernel_parts.py --selective 30`` on 10 000 and 102 400 hexahedra, 1 and 2 threads: within 3 %)."""


@njit_inline
def _rigid_fit(p, conn, X, Xc, Jinv, e):
    """The rigid part of element e's nodal values p: (mean, w) as six scalars, w = Jinv sum_a dX_a x p_a (the
    best-fitting rotation; (I - P_e) p_a = p_a - mean - w x dX_a, dX_a = X_a - Xc_e). No allocation.

    One pass over the nodes, without stored dX: sum_a dX_a x p_a = sum_a X_a x p_a - Xc x sum_a p_a (X about the
    model's centre, so the two terms cancel to a relative round-off of about 1e-16 |X| / |dX|, as the former
    one-pass form sum_a dX_a x (p_a - mean) = sum_a dX_a x p_a did through sum_a dX_a = 0). Jinv (n_el, 6) holds
    the symmetric inverse by its upper triangle (00, 01, 02, 11, 12, 22)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    t0 = 0.0
    t1 = 0.0
    t2 = 0.0
    for a in range(NODES):
        n = conn[e, a]
        d0 = p[n, 0]
        d1 = p[n, 1]
        d2 = p[n, 2]
        x0 = X[n, 0]
        x1 = X[n, 1]
        x2 = X[n, 2]
        s0 += d0
        s1 += d1
        s2 += d2
        t0 += x1 * d2 - x2 * d1
        t1 += x2 * d0 - x0 * d2
        t2 += x0 * d1 - x1 * d0
    c0 = Xc[e, 0]
    c1 = Xc[e, 1]
    c2 = Xc[e, 2]
    L0 = t0 - (c1 * s2 - c2 * s1)
    L1 = t1 - (c2 * s0 - c0 * s2)
    L2 = t2 - (c0 * s1 - c1 * s0)
    w0 = Jinv[e, 0] * L0 + Jinv[e, 1] * L1 + Jinv[e, 2] * L2
    w1 = Jinv[e, 1] * L0 + Jinv[e, 3] * L1 + Jinv[e, 4] * L2
    w2 = Jinv[e, 2] * L0 + Jinv[e, 4] * L1 + Jinv[e, 5] * L2
    return s0 / NODES, s1 / NODES, s2 / NODES, w0, w1, w2


@njit_parallel
def element_rows(p, conn, X, Xc, Jinv, c, rows):
    """rows (n_el, ROW): per element what dM_e p needs at its nodes, c_e (I - P_e) p at node a being
    c_e p_a + s_e - W_e x X_a with W_e = c_e w_e and s_e = -c_e mean_e + W_e x Xc_e [N]: row = (c_e, s_e, W_e, 0).

    Seven numbers per element instead of the eight nodal products (24): the product's traffic per element and
    iteration falls from about 780 to about 270 bytes (``_node_added`` finishes it per node). X (n_node, 3) and Xc
    (n_el, 3) the positions the rigid modes are taken at, about the model's centre [mm] (``follow``), Jinv (n_el, 6)
    [1/mm^2], c (n_el,) [t]."""
    for e in prange(conn.shape[0]):
        m0, m1, m2, w0, w1, w2 = _rigid_fit(p, conn, X, Xc, Jinv, e)
        ce = c[e]
        W0 = ce * w0
        W1 = ce * w1
        W2 = ce * w2
        rows[e, 0] = ce
        rows[e, 1] = W1 * Xc[e, 2] - W2 * Xc[e, 1] - ce * m0
        rows[e, 2] = W2 * Xc[e, 0] - W0 * Xc[e, 2] - ce * m1
        rows[e, 3] = W0 * Xc[e, 1] - W1 * Xc[e, 0] - ce * m2
        rows[e, 4] = W0
        rows[e, 5] = W1
        rows[e, 6] = W2
        rows[e, 7] = 0.0


@njit_inline
def _node_added(rows, ptr, elems, X, p, i):
    """(dM p)_i as three scalars: sum over the slots of node i (``elems``: the element of each slot, in slot
    order, an element twice where it repeats the node) of c_e p_i + s_e - W_e x X_i."""
    cs = 0.0
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    W0 = 0.0
    W1 = 0.0
    W2 = 0.0
    for k in range(ptr[i], ptr[i + 1]):
        e = elems[k]
        cs += rows[e, 0]
        s0 += rows[e, 1]
        s1 += rows[e, 2]
        s2 += rows[e, 3]
        W0 += rows[e, 4]
        W1 += rows[e, 5]
        W2 += rows[e, 6]
    x0 = X[i, 0]
    x1 = X[i, 1]
    x2 = X[i, 2]
    return (cs * p[i, 0] + s0 - (W1 * x2 - W2 * x1), cs * p[i, 1] + s1 - (W2 * x0 - W0 * x2),
            cs * p[i, 2] + s2 - (W0 * x1 - W1 * x0))


@njit_parallel
def gather_added(rows, ptr, elems, X, p, y):
    """y (n_node, 3) = dM p from the element rows of p (``element_rows``), node by node in a fixed order."""
    for i in prange(y.shape[0]):
        y0, y1, y2 = _node_added(rows, ptr, elems, X, p, i)
        y[i, 0] = y0
        y[i, 1] = y1
        y[i, 2] = y2


@njit_inline
def _total(part):
    """The chunks' partial sums added serially, in chunk order (the same bits on any thread count)."""
    total = 0.0
    for k in range(part.shape[0]):
        total += part[k]
    return total


@njit_parallel
def _direction(z, res, dinv, p, beta, q, m):
    """z = D^-1 res; p = z + beta p; q = m p (the lumped part of (M + dM) p): one pass over the nodes."""
    for i in prange(z.shape[0]):
        for j in range(3):
            z[i, j] = dinv[i, j] * res[i, j]
            p[i, j] = z[i, j] + beta * p[i, j]
            q[i, j] = m[i] * p[i, j]


@njit_parallel
def _gather_dot(rows, ptr, elems, X, q, p, free, part):
    """q += dM p from the element rows of p, and returns p . q on the free dofs, summed per chunk of CHUNK nodes
    and then serially (deterministic: one pass)."""
    n = q.shape[0]
    n_chunk = part.shape[0]
    for c in prange(n_chunk):
        s = 0.0
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            y0, y1, y2 = _node_added(rows, ptr, elems, X, p, i)
            q[i, 0] += y0
            q[i, 1] += y1
            q[i, 2] += y2
            for j in range(3):
                s += p[i, j] * q[i, j] * free[i, j]
        part[c] = s
    return _total(part)


@njit_parallel
def _step(a, res, p, q, free, alpha, dinv, part):
    """a += alpha p, res -= alpha q on the free dofs, and returns res . D^-1 res by chunks (the two updates and
    the weighted norm in one pass)."""
    n = a.shape[0]
    n_chunk = part.shape[0]
    for c in prange(n_chunk):
        s = 0.0
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            for j in range(3):
                a[i, j] += alpha * p[i, j] * free[i, j]
                res[i, j] += -alpha * q[i, j] * free[i, j]
                s += res[i, j] * res[i, j] * dinv[i, j]
        part[c] = s
    return _total(part)


@njit_parallel
def _residual(r, q, free, dinv, res, part):
    """res = (r - q) on the free dofs (0 on the others), and returns res . D^-1 res by chunks."""
    n = r.shape[0]
    n_chunk = part.shape[0]
    for c in prange(n_chunk):
        s = 0.0
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            for j in range(3):
                res[i, j] = (r[i, j] - q[i, j]) * free[i, j]
                s += res[i, j] * res[i, j] * dinv[i, j]
        part[c] = s
    return _total(part)


@njit_parallel
def _prescribed(a, free, z):
    """z = a on the prescribed dofs, 0 on the free ones; returns how many prescribed dofs are nonzero."""
    count = 0
    for i in prange(a.shape[0]):
        for j in range(3):
            z[i, j] = a[i, j] * (1.0 - free[i, j])
            if z[i, j] != 0.0:
                count += 1
    return count


@njit_inline
def _deformation_square(vn, conn, X, Xc, Jinv, e):
    """|(I - P_e) vn_e|^2 [mm^2/s^2] of element e: its nodal velocities less their rigid part, squared."""
    m0, m1, m2, w0, w1, w2 = _rigid_fit(vn, conn, X, Xc, Jinv, e)
    s = 0.0
    for a in range(NODES):
        n = conn[e, a]
        r0 = X[n, 0] - Xc[e, 0]
        r1 = X[n, 1] - Xc[e, 1]
        r2 = X[n, 2] - Xc[e, 2]
        d0 = vn[n, 0] - m0 - (w1 * r2 - w2 * r1)
        d1 = vn[n, 1] - m1 - (w2 * r0 - w0 * r2)
        d2 = vn[n, 2] - m2 - (w0 * r1 - w1 * r0)
        s += d0 * d0 + d1 * d1 + d2 * d2
    return s


@njit_parallel
def _kinetic(vn, conn, X, Xc, Jinv, c, ke_e):
    """ke_e (n_el,) = 1/2 c_e |(I - P_e) vn_e|^2 [mJ] (vn (n_node, 3) the velocities at t_n)."""
    for e in prange(conn.shape[0]):
        ke_e[e] = 0.5 * c[e] * _deformation_square(vn, conn, X, Xc, Jinv, e)


@njit_parallel
def _start(a0, a1, a2, order, v, v_old, dt_avg, free, f_ext, f_int, f_damp, r):
    """One pass over the nodes before the solve: a2 <- the warm start extrapolated from a0, a1, a2 (the last three
    cycles' accelerations, newest first; polynomial of degree ``order``) on the free dofs and the prescribed
    accelerations (v - v_old) / dt_avg on the others; r = f_ext - f_int + f_damp."""
    for i in prange(a0.shape[0]):
        for j in range(3):
            if order >= 2:
                guess = a2[i, j] + 3.0 * (a0[i, j] - a1[i, j])  # 3 a0 - 3 a1 + a2
            elif order == 1:
                guess = 2.0 * a0[i, j] - a1[i, j]
            else:
                guess = a0[i, j]
            a2[i, j] = guess * free[i, j] + (v[i, j] - v_old[i, j]) / dt_avg * (1.0 - free[i, j])
            r[i, j] = f_ext[i, j] - f_int[i, j] + f_damp[i, j]


@njit_parallel
def _velocities(v, v_old, dt_avg, a, free):
    """v = v_old + dt_avg a on the free dofs (the prescribed ones keep the constraints' v)."""
    for i in prange(v.shape[0]):
        for j in range(3):
            v[i, j] = free[i, j] * (v_old[i, j] + dt_avg * a[i, j]) + (1.0 - free[i, j]) * v[i, j]


@njit
def _kinetic_of(vn, conn, X, Xc, Jinv, dc, idx):
    """sum over the elements idx (k,) of 1/2 dc_k |(I - P_e) vn_e|^2 [mJ] (``_kinetic`` for a few elements)."""
    total = 0.0
    for k in range(idx.shape[0]):
        total += 0.5 * dc[k] * _deformation_square(vn, conn, X, Xc, Jinv, idx[k])
    return total


@njit_parallel
def _lumped(q, m, p):
    """q = m p (row-wise)."""
    for i in prange(q.shape[0]):
        for j in range(3):
            q[i, j] = m[i] * p[i, j]


@njit
def apply(p, m, conn, X, Xc, Jinv, c, ptr, elems, rows, free, part, q, snode, sK, sc):
    """q = (M + dM + sc K) p over all dofs [N for p in mm/s^2] (the CG iteration's passes; the dot product unused),
    K the implicit contact springs' entries (snode, sK; ``engine.springs``, none without them)."""
    _lumped(q, m, p)
    sp.add_product(snode, sK, sc, p, q)
    element_rows(p, conn, X, Xc, Jinv, c, rows)
    _gather_dot(rows, ptr, elems, X, q, p, free, part)


@njit
def solve(a, r, m, conn, X, Xc, Jinv, c, ptr, elems, free, dinv, tol, max_it, rows, q, res, z, p, part, snode, sK,
          sc):
    """Conjugate gradients for (M + dM + sc K) a = r on the free dofs (K: ``apply``), a (n_node, 3) holding the warm
    start on the free dofs and the prescribed accelerations on the others (kept). Returns (iterations, relative
    residual).

    Stops when sqrt(res . D^-1 res) <= tol sqrt(rhs . D^-1 rhs) (rhs = r - (dM + sc K) a_c on the free dofs) or after
    max_it iterations. Work arrays rows (n_el, ROW), q, res, z, p (n_node, 3), part (n_chunk,)."""
    # right-hand side norm: r - (M + dM + sc K) a_c on the free dofs, with a_c alone
    if _prescribed(a, free, z) > 0:
        apply(z, m, conn, X, Xc, Jinv, c, ptr, elems, rows, free, part, q, snode, sK, sc)
    else:  # symmetry planes and fixed supports: (M + dM) 0 = 0, one element pass fewer per cycle
        q[...] = 0.0
    ref = _residual(r, q, free, dinv, res, part)
    if ref == 0.0:  # nothing drives the free dofs: they do not accelerate
        for i in range(a.shape[0]):
            for j in range(3):
                a[i, j] *= 1.0 - free[i, j]
        return 0, 0.0
    apply(a, m, conn, X, Xc, Jinv, c, ptr, elems, rows, free, part, q, snode, sK, sc)
    rz = _residual(r, q, free, dinv, res, part)
    p[...] = 0.0
    it = 0
    beta = 0.0
    while rz > tol * tol * ref and it < max_it:  # four passes per iteration (fused kernels above)
        _direction(z, res, dinv, p, beta, q, m)
        sp.add_product(snode, sK, sc, p, q)
        element_rows(p, conn, X, Xc, Jinv, c, rows)
        alpha = rz / _gather_dot(rows, ptr, elems, X, q, p, free, part)
        rz_new = _step(a, res, p, q, free, alpha, dinv, part)
        beta = rz_new / rz
        rz = rz_new
        it += 1
    return it, np.sqrt(rz / ref)


@njit_inline
def _inverse_moment(X, conn, e, out):
    """out[e] (6,) = the symmetric inverse of sum_a (|dX_a|^2 I - dX_a dX_a^T) of element e at node positions X
    (dX_a = X_a - mean), by its upper triangle (00, 01, 02, 11, 12, 22); returns the mean (3 scalars) [mm]."""
    c0 = 0.0
    c1 = 0.0
    c2 = 0.0
    for a in range(NODES):
        n = conn[e, a]
        c0 += X[n, 0]
        c1 += X[n, 1]
        c2 += X[n, 2]
    c0 /= NODES
    c1 /= NODES
    c2 /= NODES
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    for a in range(NODES):
        n = conn[e, a]
        d0 = X[n, 0] - c0
        d1 = X[n, 1] - c1
        d2 = X[n, 2] - c2
        s00 += d0 * d0
        s01 += d0 * d1
        s02 += d0 * d2
        s11 += d1 * d1
        s12 += d1 * d2
        s22 += d2 * d2
    r2 = s00 + s11 + s22
    a00, a01, a02, a11, a12, a22 = r2 - s00, -s01, -s02, r2 - s11, -s12, r2 - s22
    b00 = a11 * a22 - a12 * a12
    b01 = a02 * a12 - a01 * a22
    b02 = a01 * a12 - a02 * a11
    det = a00 * b00 + a01 * b01 + a02 * b02
    out[e, 0] = b00 / det
    out[e, 1] = b01 / det
    out[e, 2] = b02 / det
    out[e, 3] = (a00 * a22 - a02 * a02) / det
    out[e, 4] = (a01 * a02 - a00 * a12) / det
    out[e, 5] = (a00 * a11 - a01 * a01) / det
    return c0, c1, c2


@njit_parallel
def _follow(v, conn, X, Xc, Jinv, Xn, c, dke):
    """Move every element's rigid modes from the node positions X to Xn (both (n_node, 3), about the model's
    centre [mm]): Xc, Jinv rewritten in place; dke (n_el,) = 1/2 c_e (|(I - P_e') v_e|^2 - |(I - P_e) v_e|^2) [mJ],
    the kinetic energy of the added mass that the move changes at the velocities v (n_node, 3) [mm/s]."""
    for e in prange(conn.shape[0]):
        old = _deformation_square(v, conn, X, Xc, Jinv, e)
        c0, c1, c2 = _inverse_moment(Xn, conn, e, Jinv)
        Xc[e, 0] = c0
        Xc[e, 1] = c1
        Xc[e, 2] = c2
        dke[e] = 0.5 * c[e] * (_deformation_square(v, conn, Xn, Xc, Jinv, e) - old)


@njit_parallel
def _diagonal(m, X, Xc, Jinv, c, ptr, elems, free, diag, dinv):
    """diag (n_node, 3) = the diagonal of M + dM and dinv = free / diag (the solve's preconditioner): per node its
    lumped mass plus, over its slots in slot order, c_e (1 - 1/n - (S_a Jinv_e S_a^T)_jj) with S_a = [X_a - Xc_e]x
    (the diagonal of I - P_e, as ``projector_diagonal``)."""
    for i in prange(m.shape[0]):
        t0 = 0.0
        t1 = 0.0
        t2 = 0.0
        for k in range(ptr[i], ptr[i + 1]):
            e = elems[k]
            r0 = X[i, 0] - Xc[e, 0]
            r1 = X[i, 1] - Xc[e, 1]
            r2 = X[i, 2] - Xc[e, 2]
            j00, j01, j02, j11, j12, j22 = Jinv[e, 0], Jinv[e, 1], Jinv[e, 2], Jinv[e, 3], Jinv[e, 4], Jinv[e, 5]
            # rows of S: (0, -r2, r1), (r2, 0, -r0), (-r1, r0, 0); (S J S^T)_jj = S_j . J S_j
            q0 = j11 * r2 * r2 - 2.0 * j12 * r2 * r1 + j22 * r1 * r1
            q1 = j00 * r2 * r2 - 2.0 * j02 * r2 * r0 + j22 * r0 * r0
            q2 = j00 * r1 * r1 - 2.0 * j01 * r1 * r0 + j11 * r0 * r0
            t0 += c[e] * (1.0 - 1.0 / NODES - q0)
            t1 += c[e] * (1.0 - 1.0 / NODES - q1)
            t2 += c[e] * (1.0 - 1.0 / NODES - q2)
        diag[i, 0] = m[i] + t0
        diag[i, 1] = m[i] + t1
        diag[i, 2] = m[i] + t2
        for j in range(3):
            dinv[i, j] = free[i, j] / diag[i, j]


def projector_diagonal(dX: np.ndarray, Jinv: np.ndarray) -> np.ndarray:
    """(k, 8, 3): the diagonal of I - P_e at each slot of k elements, from dX (k, 8, 3) [mm] and Jinv (k, 6):
    1 - 1/n from the translations, less S_a Jinv S_a^T from the rotations (S_a = [dX_a]x)."""
    J = Jinv[:, [0, 1, 2, 1, 3, 4, 2, 4, 5]].reshape(-1, 3, 3)
    S = np.zeros(dX.shape + (3,))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -dX[..., 2], dX[..., 1], -dX[..., 0]
    S -= np.swapaxes(S, -1, -2)
    return 1.0 - (1.0 / dX.shape[1] + np.einsum("eaij,ejk,eaik->eai", S, J, S))


class SelectiveMass:
    """The added mass of the hexahedral groups and its per-cycle solve; the engine's state of it.

    Arrays: ``a`` (n_node, 3) last accelerations [mm/s^2] (the warm start, saved in checkpoints), ``g`` (n_node, 3)
    = dM a [N], the inertia of the added mass (part of the reactions the engine books).
    Counters: cycles solved, iterations in all and the largest per cycle, cycles that hit the cap.
    """

    def __init__(self, conns: list[np.ndarray], X: np.ndarray):
        n_node = len(X)
        conn = np.concatenate(conns)
        if conn.shape[1] != NODES:
            raise ValueError(f"selective mass is built for {NODES}-node hexahedra, not {conn.shape[1]}-node cells")
        # constants, read-only (so checkpoints skip them): int32 indices (half the bytes per iteration) and the
        # model's centre; the positions the rigid modes are taken at (X, Xc, Jinv: ``follow``) are about that centre
        # (the rigid fit's cancellation scales with |X| / |dX|)
        self.conn = np.ascontiguousarray(conn, np.int32)
        ptr, slots = node_slots(self.conn, n_node)
        self.ptr, self.elems = ptr, (slots // NODES).astype(np.int32)  # each node's slots as elements, slot order
        self.centre = 0.5 * (X.min(axis=0) + X.max(axis=0))
        self.X = np.ascontiguousarray(X - self.centre, float)
        n_el = len(self.conn)
        self.Xc = np.zeros((n_el, 3))  # element means of X [mm]
        self.Jinv = np.zeros((n_el, 6))  # inverse moments of the element nodes about them [1/mm^2]
        self.c = np.zeros(n_el)
        # the rigid fit at the reference positions: follow's kernel from X to X at rest (no energy to measure)
        _follow(np.zeros_like(self.X), self.conn, self.X, self.Xc, self.Jinv, self.X, self.c, np.zeros(n_el))
        for a in (self.conn, self.ptr, self.elems, self.centre):
            a.flags.writeable = False  # X, Xc, Jinv follow the elements (``follow``): saved with checkpoints
        self.free = np.ones((n_node, 3))
        self.dinv = np.ones((n_node, 3))
        self.diag = np.ones((n_node, 3))
        self.m = np.ones(n_node)
        self.tol, self.max_it = 0.0, 0  # the step's (tolerance, cap): set by set_step, which activates
        self.active = False
        self.a = np.zeros((n_node, 3))
        self.a_last = np.zeros((n_node, 3))  # the two cycles before (warm-start extrapolation)
        self.a_last2 = np.zeros((n_node, 3))
        self.g = np.zeros((n_node, 3))
        self._product = np.zeros((n_node, 3))  # dM p of ``product``
        self._work = [np.zeros((n_el, ROW))] + [np.zeros((n_node, 3)) for _ in range(4)]
        self._part = np.zeros((n_node + CHUNK - 1) // CHUNK)
        self._ke = np.zeros(n_el)
        self._r = np.zeros((n_node, 3))
        self._no_springs = (np.zeros(0, np.int64), np.zeros((0, 6)), np.zeros((0, 3)))
        self._vn = np.zeros((n_node, 3))  # scratch of ``add``: mid-cycle velocities of the raised elements' nodes
        self._raise = (np.zeros(n_el), np.zeros(n_el), np.zeros((n_node, 3)))  # scratch of ``conserve``
        self._moved = (np.zeros((n_node, 3)), np.zeros(n_el))  # scratch of ``follow``
        self.cycles = 0
        self.iterations = 0
        self.max_iterations = 0
        self.capped = 0
        self.last_residual = 0.0
        self.ke_last = 0.0  # added kinetic energy at the last cycle that computed it [mJ]

    def _complement_diagonal(self, idx: np.ndarray) -> np.ndarray:
        """(k, 8, 3) diagonal of I - P_e at the slots of the elements idx (k,) (``add``'s O(k) update)."""
        conn = self.conn[idx]
        return projector_diagonal(self.X[conn] - self.Xc[idx][:, None, :], self.Jinv[idx])

    def product(self, p: np.ndarray) -> np.ndarray:
        """dM p (n_node, 3) [N] for p (n_node, 3) [mm/s^2]: the solve's own element rows and node sums. The result
        is a buffer of the solver's, overwritten by the next call (the damping of the added mass calls this every
        cycle of a dwell: no allocation); the element rows use the solve's scratch, free between solves."""
        rows, y = self._work[0], self._product
        element_rows(p, self.conn, self.X, self.Xc, self.Jinv, self.c, rows)
        gather_added(rows, self.ptr, self.elems, self.X, p, y)
        return y

    def set_step(self, betas: list[np.ndarray] | None, element_mass: list[np.ndarray], m: np.ndarray,
                 free: np.ndarray, cg: tuple[float, int]) -> None:
        """A step's factors beta (per group (n_el,), None: no added mass), element masses (per group (n_el,) [t]),
        lumped nodal mass m (n_node,) [t], free-dof mask (n_node, 3) and (tolerance, iteration cap)."""
        self.active = betas is not None
        if not self.active:
            return
        n = self.conn.shape[1]
        self.c[:] = np.concatenate([b * me / n for b, me in zip(betas, element_mass)])
        self.m = np.ascontiguousarray(m, float)
        self.free = np.ascontiguousarray(free, float)
        self._precondition()
        self.tol, self.max_it = float(cg[0]), int(cg[1])

    def add(self, idx: np.ndarray, dc: np.ndarray, v=None, v_old=None) -> float:
        """Raise the added mass of elements idx (k,) by dc (k,) [t] (c_e = beta_e m_e / n) and the preconditioner
        with it; returns the kinetic energy it adds at the current velocities, 1/2 sum dc_e |(I - P_e) v_e|^2 [mJ]
        (v_n as ``book`` takes it; 0 without velocities). O(k) work: the stroke's tracking raises a few elements on
        most cycles late in a forming run, so a pass over every element here cost more than the rest of the
        stable-step update."""
        self.c[idx] += dc
        nodes = self.conn[idx]
        np.add.at(self.diag, nodes.ravel(), (dc[:, None, None] * self._complement_diagonal(idx)).reshape(-1, 3))
        touched = np.unique(nodes)
        self.dinv[touched] = self.free[touched] / self.diag[touched]
        if v is None:
            return 0.0
        self._vn[touched] = 0.5 * (v_old[touched] + v[touched])  # the only nodes _kinetic_of reads
        return _kinetic_of(self._vn, self.conn, self.X, self.Xc, self.Jinv, dc, idx)

    def _precondition(self) -> None:
        """diag (n_node, 3) = the diagonal of M + dM, dinv = free / diag: the solve's preconditioner, rebuilt in
        place from the current c, m, free and rigid modes."""
        _diagonal(self.m, self.X, self.Xc, self.Jinv, self.c, self.ptr, self.elems, self.free, self.diag, self.dinv)

    def follow(self, x: np.ndarray, v: np.ndarray, precondition: bool = True) -> float:
        """Take every element's rigid modes at the positions x (n_node, 3) [mm] (the projectors P_e follow the
        elements as they turn and shear; module docstring) and the preconditioner with them. Returns the kinetic
        energy of the added mass this changes at the velocities v (n_node, 3) [mm/s], 1/2 v^T (dM' - dM) v [mJ]:
        the engine books it (``mass_corotation_work``), as nothing else supplies it. One pass over the elements and
        one over the nodes; bitwise the same on any thread count (no reduction across threads but the final sum,
        which numpy takes serially). ``precondition=False`` leaves the preconditioner to the caller (a step's start:
        ``set_step`` rebuilds it)."""
        Xn, dke = self._moved
        np.subtract(x, self.centre, out=Xn)
        _follow(v, self.conn, self.X, self.Xc, self.Jinv, Xn, self.c, dke)
        self._moved = (self.X, dke)
        self.X = Xn
        if precondition:
            self._precondition()
        return float(dke.sum())

    def conserve(self, idx: np.ndarray, dc: np.ndarray, v: np.ndarray, force=None, dt: float = 0.0) -> float:
        """After ``add`` raised elements idx (k,) by dc (k,) [t]: correct the velocities v (n_node, 3) [mm/s] on the
        free dofs so that (M + dM) v keeps the value it had with the mass before the raise (the prescribed dofs keep
        theirs). The new mass joins at rest relative to each element's rigid motion: momentum and the lumped
        translational momentum 1^T M v are kept (to the solve's tolerance), the deformation modes slow down.

        Returns the energy to book [mJ]: the change of the half-step kinetic energy 1/2 v^T (M + dM) v (at most 0
        where every dof is free), plus 1/2 dt force . dv for the ledger, which measures the kinetic energy at t_n+1
        from 1/2 (v + v_next) with v_next = v + dt (M + dM)^-1 force (force (n_node, 3) [N]: the net nodal force
        that drives the next kick, dt [s] the step just taken); without that term the booking is first-order in
        dt (a helper's check on a spring chain with a changing mass: ledger error 0.28 -> 0.10 at 0.2 of the
        critical step, 0.057 -> 0.0065 at 0.05).

        The solve (M + dM)_ff dv_f = -(dM_raise v)_f by the cycle's conjugate gradients, from dv = 0, with the
        step's tolerance and cap (counted in the cycle's iterations and capped cycles; no contact springs: they
        are stiffness, not mass). Costs about one cycle's solve and two kinetic-energy passes on the cycles that
        raise."""
        raise_c, old_c, dv = self._raise
        raise_c[idx] = dc
        np.subtract(self.c, raise_c, out=old_c)
        ke_old = self._whole_kinetic(v, old_c)
        rows = self._work[0]
        element_rows(v, self.conn, self.X, self.Xc, self.Jinv, raise_c, rows)
        r = self._r
        gather_added(rows, self.ptr, self.elems, self.X, v, r)
        r *= -1.0
        dv.fill(0.0)
        it = self.solve_mass(dv, r)
        raise_c[idx] = 0.0
        self.iterations += it
        self.max_iterations = max(self.max_iterations, it)
        self.capped += it >= self.max_it
        v += dv  # zero on the prescribed dofs (the solve moves only free ones)
        change = self._whole_kinetic(v, self.c) - ke_old
        if force is not None:
            change += 0.5 * dt * float(np.sum(force * dv))
        return change

    def solve_mass(self, out: np.ndarray, r: np.ndarray, tol: float | None = None, max_it: int | None = None) -> int:
        """Solve (M + dM)_ff out_f = r_f [N] for out (n_node, 3) [mm/s^2] by the cycle's conjugate gradients,
        starting from out's free dofs and keeping its prescribed ones; no contact springs (they are stiffness, not
        mass). tol and max_it default to the step's. Returns the iterations taken. Uses the solve's scratch, so
        not during a cycle's solve (``conserve`` and studies/critical_step.py call it between cycles)."""
        rows, q, res, z, p = self._work
        snode, sK, _ = self._no_springs
        tol = self.tol if tol is None else tol
        max_it = self.max_it if max_it is None else max_it
        it, _ = solve(out, r, self.m, self.conn, self.X, self.Xc, self.Jinv, self.c, self.ptr, self.elems, self.free,
                      self.dinv, tol, max_it, rows, q, res, z, p, self._part, snode, sK, 0.0)
        return it

    def _whole_kinetic(self, v: np.ndarray, c: np.ndarray) -> float:
        """1/2 v^T (M + dM) v [mJ] with the added-mass factors c (n_el,) [t], in ``book``'s scratch (free between
        cycles: ``book`` refills it before it reads it)."""
        _kinetic(v, self.conn, self.X, self.Xc, self.Jinv, c, self._ke)
        return float(self._ke.sum()) + 0.5 * float(np.einsum("i,ij,ij->", self.m, v, v))

    def accelerate(self, v, v_old, f_ext, f_int, f_damp, dt_avg, springs=None, dt=0.0) -> None:
        """After the lumped kick and the constraints: a_c = (v - v_old) / dt_avg on prescribed dofs, a_f from the
        solve with r = f_ext - f_int + f_damp, v = v_old + dt_avg a on free dofs; then g = dM a. With implicit
        contact springs (``engine.springs.Springs``, dt the step) the solve is (M + dM + dt dt_avg K) a = r - dt K
        (v_old - v_tool) on their nodes, its preconditioner with them."""
        # warm start: the free dofs' accelerations extrapolated from the last three cycles (quadratic; linear on
        # the second cycle). Against the last cycle's alone, mean iterations per cycle measured on the first 6 000
        # cycles of the coarse tetrahedron 10.6 -> 7.7, double dome 0/90 8.5 -> 6.8, and on 0.15 s of the 5 mm weft
        # strip 23.4 -> 21.0 (linear extrapolation: 9.1, 7.5, 20.9).
        free, r = self.free, self._r
        a0, a1, a2 = self.a, self.a_last, self.a_last2
        _start(a0, a1, a2, min(WARM_START_ORDER, self.cycles - 1), v, v_old, dt_avg, free, f_ext, f_int, f_damp, r)
        self.a, self.a_last, self.a_last2 = a2, a0, a1
        rows, q, res, z, p = self._work
        snode, sK, vt = springs.entries() if springs is not None else self._no_springs
        sc = dt * dt_avg
        if len(snode):
            sp.add_rhs(snode, sK, vt, dt, v_old, r)
            sp.precondition(snode, sK, sc, self.diag, free, self.dinv, True, springs.seen)
        it, rel = solve(self.a, r, self.m, self.conn, self.X, self.Xc, self.Jinv, self.c, self.ptr, self.elems, free,
                        self.dinv, self.tol, self.max_it, rows, q, res, z, p, self._part, snode, sK, sc)
        if len(snode):
            sp.precondition(snode, sK, sc, self.diag, free, self.dinv, False, springs.seen)
        _velocities(v, v_old, dt_avg, self.a, free)
        element_rows(self.a, self.conn, self.X, self.Xc, self.Jinv, self.c, rows)
        gather_added(rows, self.ptr, self.elems, self.X, self.a, self.g)
        self.cycles += 1
        self.iterations += it
        self.max_iterations = max(self.max_iterations, it)
        self.capped += it >= self.max_it
        self.last_residual = float(rel)

    def work(self, dx) -> float:
        """What the engine's drift leaves out of the reactions' work over the last increment dx (n_node, 3), called
        before the positions move: its current reaction lacks g (the previous one was completed by ``book``), so
        the trapezoidal increment lacks g . dx / 2 [mJ]."""
        return 0.5 * float(np.sum(self.g * dx))

    def kinetic(self, v: np.ndarray, c: np.ndarray) -> float:
        """1/2 sum c_e |(I - P_e) v_e|^2 [mJ] for velocities v (n_node, 3) [mm/s] and factors c (n_el,) [t] (a step
        boundary's change of the added mass, ``engine.step_mass``; ``book`` keeps its own last value)."""
        ke = np.zeros(len(c))
        _kinetic(np.ascontiguousarray(v), self.conn, self.X, self.Xc, self.Jinv, np.ascontiguousarray(c), ke)
        return float(ke.sum())

    def book(self, v, v_old, reaction, fe_prev, first: bool, kinetic: bool = True) -> float:
        """After the engine's drift: the reactions and the stored external force include dM a; returns the added
        kinetic energy 1/2 v_n^T dM v_n at t_n [mJ]. With ``kinetic`` False (no history row this cycle: only rows
        and the first cycle's reference energy read the kinetic energy; other cycles only test it for being finite,
        which the lumped part computed every cycle from the same v already does) the last value computed is
        returned instead, and one element pass is saved."""
        reaction += self.g
        fe_prev += self.g
        if kinetic or first:
            vn = v_old if first else 0.5 * (v_old + v)
            _kinetic(vn, self.conn, self.X, self.Xc, self.Jinv, self.c, self._ke)
            self.ke_last = float(self._ke.sum())
        return self.ke_last
