"""Selective mass scaling: a non-diagonal added mass on the deformation modes of each element, solved per cycle.

Method: Olovsson, Simonsson & Unosson, "Selective mass scaling for explicit finite element analyses", IJNME 63
(2005); the iterative solve as in Olovsson & Simonsson, "Iterative solution technique in selective mass scaling",
Comm. Numer. Meth. Engng 22 (2006). Per element e with n nodes, lumped element mass m_e [t] and factor beta_e:

    dM_e = beta_e (m_e / n) (I - P_e),   P_e the orthogonal projector on the element's 6 rigid modes (3n x 3n)

with the rigid modes (translations c, rotations w x dX_a) taken at the reference positions dX_a = X_a - mean(X).

* ``dM_e`` vanishes on rigid motion: total mass, momentum (1^T (M + dM) v = sum m v), the response to a uniform
  acceleration (gravity) and, for small rotations, the rotary inertia are those of the lumped mass M.
* For an element whose lumped masses are equal (m_e / n: every parallelepiped), each deformation mode phi of
  (K_e, M_e) is orthogonal to the rigid modes (they span the null space of the symmetric K_e), so
  (M_e + dM_e) phi = (1 + beta_e) M_e phi: every nonzero element eigenvalue divides by 1 + beta_e and the element
  step grows by sqrt(1 + beta_e), as with a density rho (1 + beta_e); by the element eigenvalue bound the
  assembled step does too.
* A collapsed hexahedron (the prisms of ``mesh.block.lattice: diagonal``) repeats a node in two slots, so its
  lumped masses are not equal and that node takes two slots' share of dM_e: the step gain on a prism is below
  sqrt(1 + beta_e) (measured 2.06 against 2.15 at beta = 3.6, 3.7 % short), which the prism's conservative element
  step estimate (about 1.36x below its true step) covers; not corrected.
* dM is constant, so central differences keep their energy conservation with kinetic energy 1/2 v^T (M + dM) v;
  1/2 v^T dM_e v = 1/2 beta_e (m_e / n) |(I - P_e) v_e|^2 (booked in the engine's kinetic energy).

Why the reference rigid modes, and what it costs: the current ones would follow the element as it turns, and a
mass that changes with the configuration is no longer conserved by central differences (and must be rebuilt every
cycle). With the reference projector, an element turned by an angle phi sees a share of order sin(phi)^2 of its
rotary inertia scaled by 1 + beta_e. The simpler projector on translations alone (I - 1 1^T / n, frame-indifferent)
scales the whole rotary inertia of every element, (L_e^2 + h_e^2) / 4 per unit mass with lumped nodes: on a
slender strip with 5 mm elements and a 5x step that moves the first bending frequency by 1.7 %, the six-mode
projector by less than 0.01 % (``tests/test_selective_mass.py``).

Per cycle the engine forms r = f_ext - f_int + f_damp, and the constraints fix the accelerations a_c of prescribed
dofs; the free accelerations solve (M + dM)_ff a_f = r_f - dM_fc a_c by conjugate gradients preconditioned by the
diagonal, warm-started from the last cycle's a, with element-by-element products (no assembled matrix) and a
deterministic gather (CSR node -> slots, ``engine.gather``); dot products are summed per fixed chunk of nodes and
then serially, so runs are bitwise identical on any thread count.

Shapes: nodal arrays (n_node, 3) [mm/s^2, N, mm/s]; m (n_node,) [t]; conn (n_el, n) node indices; c (n_el,)
= beta_e m_e / n [t]; free (n_node, 3) 1.0 on free dofs, 0.0 on prescribed ones.
"""

from __future__ import annotations

import numpy as np

from fdeck.engine.gather import gather_add, node_slots, node_sum, slot_rows
from fdeck.jit import njit, njit_inline, njit_parallel, prange

WARM_START_ORDER = 2
"""Degree of the polynomial through the last cycles' accelerations that starts each solve (0: the last cycle's)."""

CHUNK = 256  # nodes per partial sum of a dot product (fixed, so the sums do not depend on the thread count)


NODES = 8  # hexahedra only (shells are refused): a constant trip count lets the compiler unroll the node loops


@njit_inline
def _rigid_fit(p, conn, dX, Jinv, e):
    """The rigid part of element e's nodal values p: (mean, w) as six scalars, w = Jinv sum_a dX_a x p_a (the
    best-fitting rotation; (I - P_e) p_a = p_a - mean - w x dX_a). No allocation (called per element).

    One pass over the nodes: sum_a dX_a x (p_a - mean) is written sum_a dX_a x p_a because sum_a dX_a = 0 (up to
    round-off, relative 1e-16 |X| / |dX|). With the node count a constant as well, element_added went 0.057 ->
    0.037 us per element (``benchmarks/kernel_parts.py fbar fabric_hyper_3weave --selective 30``, 10 000
    hexahedra, one thread; the bits differ in the last place)."""
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    L0 = 0.0
    L1 = 0.0
    L2 = 0.0
    for a in range(NODES):
        n = conn[e, a]
        d0 = p[n, 0]
        d1 = p[n, 1]
        d2 = p[n, 2]
        m0 += d0
        m1 += d1
        m2 += d2
        L0 += dX[e, a, 1] * d2 - dX[e, a, 2] * d1
        L1 += dX[e, a, 2] * d0 - dX[e, a, 0] * d2
        L2 += dX[e, a, 0] * d1 - dX[e, a, 1] * d0
    w0 = Jinv[e, 0, 0] * L0 + Jinv[e, 0, 1] * L1 + Jinv[e, 0, 2] * L2
    w1 = Jinv[e, 1, 0] * L0 + Jinv[e, 1, 1] * L1 + Jinv[e, 1, 2] * L2
    w2 = Jinv[e, 2, 0] * L0 + Jinv[e, 2, 1] * L1 + Jinv[e, 2, 2] * L2
    return m0 / NODES, m1 / NODES, m2 / NODES, w0, w1, w2


@njit_parallel
def element_added(p, conn, dX, Jinv, c, ye):
    """ye (n_el, 8, 3) = c_e (I - P_e) p_e for each element: the element products dM_e p. dX (n_el, 8, 3)
    reference positions about the element's centre [mm], Jinv (n_el, 3, 3) inverse of sum_a |dX_a|^2 I - dX_a dX_a
    [1/mm^2]."""
    for e in prange(conn.shape[0]):
        m0, m1, m2, w0, w1, w2 = _rigid_fit(p, conn, dX, Jinv, e)
        ce = c[e]
        for a in range(NODES):
            n = conn[e, a]
            ye[e, a, 0] = ce * (p[n, 0] - m0 - (w1 * dX[e, a, 2] - w2 * dX[e, a, 1]))
            ye[e, a, 1] = ce * (p[n, 1] - m1 - (w2 * dX[e, a, 0] - w0 * dX[e, a, 2]))
            ye[e, a, 2] = ce * (p[n, 2] - m2 - (w0 * dX[e, a, 1] - w1 * dX[e, a, 0]))


@njit_parallel
def _scaled(q, m, p):
    """q = m p (row-wise)."""
    for i in prange(q.shape[0]):
        for j in range(3):
            q[i, j] = m[i] * p[i, j]


@njit_inline
def _total(part):
    """The chunks' partial sums added serially, in chunk order (the same bits on any thread count)."""
    total = 0.0
    for k in range(part.shape[0]):
        total += part[k]
    return total


@njit_parallel
def dot(a, b, w, part):
    """sum of a * b * w over (n_node, 3), by fixed chunks of CHUNK nodes summed serially (deterministic)."""
    n = a.shape[0]
    n_chunk = part.shape[0]
    for k in prange(n_chunk):
        s = 0.0
        for i in range(k * CHUNK, min(n, (k + 1) * CHUNK)):
            for j in range(3):
                s += a[i, j] * b[i, j] * w[i, j]
        part[k] = s
    return _total(part)


@njit_parallel
def _direction(z, res, dinv, p, beta, q, m):
    """z = D^-1 res; p = z + beta p; q = m p (the lumped part of (M + dM) p): one pass over the nodes."""
    for i in prange(z.shape[0]):
        for j in range(3):
            z[i, j] = dinv[i, j] * res[i, j]
            p[i, j] = z[i, j] + beta * p[i, j]
            q[i, j] = m[i] * p[i, j]


@njit_parallel
def _gather_dot(ye, ptr, slots, q, p, free, part):
    """q += the element products ye (n_el, 8, 3) gathered per node in a fixed order (``engine.gather``), and
    returns p . q on the free dofs, summed per chunk of CHUNK nodes and then serially (the same operations, in the
    same order, as ``gather_add`` followed by ``dot``: one pass)."""
    n = q.shape[0]
    n_chunk = part.shape[0]
    rows = slot_rows(ye)
    for c in prange(n_chunk):
        s = 0.0
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            s0, s1, s2 = node_sum(rows, ptr, slots, i)
            q[i, 0] += s0
            q[i, 1] += s1
            q[i, 2] += s2
            for j in range(3):
                s += p[i, j] * q[i, j] * free[i, j]
        part[c] = s
    return _total(part)


@njit_parallel
def _step(a, res, p, q, free, alpha, dinv, part):
    """a += alpha p, res -= alpha q on the free dofs, and returns res . D^-1 res by chunks (as ``_axpy`` twice and
    ``dot``, in one pass)."""
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


@njit_inline
def _deformation_square(vn, conn, dX, Jinv, e):
    """|(I - P_e) vn_e|^2 [mm^2/s^2] of element e: its nodal velocities less their rigid part, squared."""
    m0, m1, m2, w0, w1, w2 = _rigid_fit(vn, conn, dX, Jinv, e)
    s = 0.0
    for a in range(NODES):
        n = conn[e, a]
        d0 = vn[n, 0] - m0 - (w1 * dX[e, a, 2] - w2 * dX[e, a, 1])
        d1 = vn[n, 1] - m1 - (w2 * dX[e, a, 0] - w0 * dX[e, a, 2])
        d2 = vn[n, 2] - m2 - (w0 * dX[e, a, 1] - w1 * dX[e, a, 0])
        s += d0 * d0 + d1 * d1 + d2 * d2
    return s


@njit_parallel
def _kinetic(vn, conn, dX, Jinv, c, ke_e):
    """ke_e (n_el,) = 1/2 c_e |(I - P_e) vn_e|^2 [mJ] (vn (n_node, 3) the velocities at t_n)."""
    for e in prange(conn.shape[0]):
        ke_e[e] = 0.5 * c[e] * _deformation_square(vn, conn, dX, Jinv, e)


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
def _kinetic_of(vn, conn, dX, Jinv, dc, idx):
    """sum over the elements idx (k,) of 1/2 dc_k |(I - P_e) vn_e|^2 [mJ] (``_kinetic`` for a few elements)."""
    total = 0.0
    for k in range(idx.shape[0]):
        total += 0.5 * dc[k] * _deformation_square(vn, conn, dX, Jinv, idx[k])
    return total


@njit
def apply(p, m, conn, dX, Jinv, c, ptr, slots, ye, q):
    """q = (M + dM) p over all dofs [N for p in mm/s^2]."""
    _scaled(q, m, p)
    element_added(p, conn, dX, Jinv, c, ye)
    gather_add(ye, ptr, slots, q)


@njit
def solve(a, r, m, conn, dX, Jinv, c, ptr, slots, free, dinv, tol, max_it, ye, q, res, z, p, part):
    """Conjugate gradients for (M + dM) a = r on the free dofs, a (n_node, 3) holding the warm start on the free
    dofs and the prescribed accelerations on the others (kept). Returns (iterations, relative residual).

    Stops when sqrt(res . D^-1 res) <= tol sqrt(rhs . D^-1 rhs) (rhs = r - dM a_c on the free dofs) or after
    max_it iterations. Work arrays ye (n_el, 8, 3), q, res, z, p (n_node, 3), part (n_chunk,)."""
    # right-hand side norm: r - (M + dM) a_c on the free dofs, with a_c alone
    prescribed = False
    for i in range(a.shape[0]):
        for j in range(3):
            z[i, j] = a[i, j] * (1.0 - free[i, j])
            prescribed = prescribed or z[i, j] != 0.0
    if prescribed:
        apply(z, m, conn, dX, Jinv, c, ptr, slots, ye, q)
    else:  # symmetry planes and fixed supports: (M + dM) 0 = 0, one element pass fewer per cycle
        q[...] = 0.0
    for i in range(a.shape[0]):
        for j in range(3):
            res[i, j] = (r[i, j] - q[i, j]) * free[i, j]
    ref = dot(res, res, dinv, part)
    if ref == 0.0:  # nothing drives the free dofs: they do not accelerate
        for i in range(a.shape[0]):
            for j in range(3):
                a[i, j] *= 1.0 - free[i, j]
        return 0, 0.0
    apply(a, m, conn, dX, Jinv, c, ptr, slots, ye, q)
    for i in range(a.shape[0]):
        for j in range(3):
            res[i, j] = (r[i, j] - q[i, j]) * free[i, j]
            p[i, j] = 0.0
    rz = dot(res, res, dinv, part)
    it = 0
    beta = 0.0
    while rz > tol * tol * ref and it < max_it:  # four passes per iteration (fused kernels above)
        _direction(z, res, dinv, p, beta, q, m)
        element_added(p, conn, dX, Jinv, c, ye)
        alpha = rz / _gather_dot(ye, ptr, slots, q, p, free, part)
        rz_new = _step(a, res, p, q, free, alpha, dinv, part)
        beta = rz_new / rz
        rz = rz_new
        it += 1
    return it, np.sqrt(rz / ref)


class SelectiveMass:
    """The added mass of the hexahedral groups and its per-cycle solve; the engine's state of it.

    Arrays: ``a`` (n_node, 3) last accelerations [mm/s^2] (the warm start, saved in checkpoints), ``g`` (n_node, 3)
    = dM a [N], the inertia of the added mass (part of the reactions the engine books).
    Counters: cycles solved, iterations in all and the largest per cycle, cycles that hit the cap.
    """

    def __init__(self, conns: list[np.ndarray], X: np.ndarray):
        n_node = len(X)
        self.conn = np.ascontiguousarray(np.concatenate(conns), np.int64)
        if self.conn.shape[1] != NODES:
            raise ValueError(f"selective mass is built for {NODES}-node hexahedra, "
                             f"not {self.conn.shape[1]}-node cells")
        self.ptr, self.slots = node_slots(self.conn, n_node)
        n_el, k = self.conn.shape
        Xe = X[self.conn]
        self.dX = Xe - Xe.mean(axis=1, keepdims=True)  # (n_el, 8, 3) [mm]
        r2 = np.einsum("eai,eai->e", self.dX, self.dX)
        J = r2[:, None, None] * np.eye(3) - np.einsum("eai,eaj->eij", self.dX, self.dX)
        self.Jinv = np.linalg.inv(J)  # (n_el, 3, 3): rotations fitted to the reference positions
        self.c = np.zeros(n_el)
        self.free = np.ones((n_node, 3))
        self.dinv = np.ones((n_node, 3))
        self.diag = np.ones((n_node, 3))
        self.q_diag = np.zeros((n_el, k, 3))
        self.m = np.ones(n_node)
        self.tol, self.max_it = 0.0, 0  # the step's (tolerance, cap): set by set_step, which activates
        self.active = False
        self.a = np.zeros((n_node, 3))
        self.a_last = np.zeros((n_node, 3))  # the two cycles before (warm-start extrapolation)
        self.a_last2 = np.zeros((n_node, 3))
        self.g = np.zeros((n_node, 3))
        self._work = [np.zeros((n_el, k, 3))] + [np.zeros((n_node, 3)) for _ in range(4)]
        self._part = np.zeros((n_node + CHUNK - 1) // CHUNK)
        self._ke = np.zeros(n_el)
        self._r = np.zeros((n_node, 3))
        self._vn = np.zeros((n_node, 3))  # scratch of ``add``: mid-cycle velocities of the raised elements' nodes
        self.cycles = 0
        self.iterations = 0
        self.max_iterations = 0
        self.capped = 0
        self.last_residual = 0.0
        self.ke_last = 0.0  # added kinetic energy at the last cycle that computed it [mJ]

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
        # diagonal of P_e: 1/n from the translations, S_a Jinv S_a^T from the rotations (S_a = [dX_a]x)
        S = np.zeros(self.dX.shape + (3,))
        S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -self.dX[..., 2], self.dX[..., 1], -self.dX[..., 0]
        S -= np.swapaxes(S, -1, -2)
        p_diag = 1.0 / n + np.einsum("eaij,ejk,eaik->eai", S, self.Jinv, S)
        self.q_diag = 1.0 - p_diag  # (n_el, 8, 3) diagonal of I - P_e
        self.diag = np.repeat(self.m[:, None], 3, axis=1)
        np.add.at(self.diag, self.conn.ravel(), (self.c[:, None, None] * self.q_diag).reshape(-1, 3))
        self.dinv = self.free / self.diag
        self.tol, self.max_it = float(cg[0]), int(cg[1])

    def add(self, idx: np.ndarray, dc: np.ndarray, v, v_old) -> float:
        """Raise the added mass of elements idx (k,) by dc (k,) [t] (c_e = beta_e m_e / n) and the preconditioner
        with it; returns the kinetic energy it adds at the current velocities, 1/2 sum dc_e |(I - P_e) v_e|^2 [mJ]
        (v_n as ``book`` takes it). O(k) work: the stroke's tracking raises a few elements on most cycles late in a
        forming run, so a pass over every element here cost more than the rest of the stable-step update."""
        self.c[idx] += dc
        nodes = self.conn[idx]
        np.add.at(self.diag, nodes.ravel(), (dc[:, None, None] * self.q_diag[idx]).reshape(-1, 3))
        touched = np.unique(nodes)
        self.dinv[touched] = self.free[touched] / self.diag[touched]
        self._vn[touched] = 0.5 * (v_old[touched] + v[touched])  # the only nodes _kinetic_of reads
        return _kinetic_of(self._vn, self.conn, self.dX, self.Jinv, dc, idx)

    def accelerate(self, v, v_old, f_ext, f_int, f_damp, dt_avg) -> None:
        """After the lumped kick and the constraints: a_c = (v - v_old) / dt_avg on prescribed dofs, a_f from the
        solve with r = f_ext - f_int + f_damp, v = v_old + dt_avg a on free dofs; then g = dM a."""
        # warm start: the free dofs' accelerations extrapolated from the last three cycles (quadratic; linear on
        # the second cycle). Against the last cycle's alone, mean iterations per cycle measured on the first 6 000
        # cycles of the coarse tetrahedron 10.6 -> 7.7, double dome 0/90 8.5 -> 6.8, and on 0.15 s of the 5 mm weft
        # strip 23.4 -> 21.0 (linear extrapolation: 9.1, 7.5, 20.9).
        free, r = self.free, self._r
        a0, a1, a2 = self.a, self.a_last, self.a_last2
        _start(a0, a1, a2, min(WARM_START_ORDER, self.cycles - 1), v, v_old, dt_avg, free, f_ext, f_int, f_damp, r)
        self.a, self.a_last, self.a_last2 = a2, a0, a1
        ye, q, res, z, p = self._work
        it, rel = solve(self.a, r, self.m, self.conn, self.dX, self.Jinv, self.c, self.ptr, self.slots, free,
                        self.dinv, self.tol,
                        self.max_it, ye, q, res, z, p, self._part)
        _velocities(v, v_old, dt_avg, self.a, free)
        element_added(self.a, self.conn, self.dX, self.Jinv, self.c, ye)
        self.g.fill(0.0)
        gather_add(ye, self.ptr, self.slots, self.g)
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
            _kinetic(vn, self.conn, self.dX, self.Jinv, self.c, self._ke)
            self.ke_last = float(self._ke.sum())
        return self.ke_last
