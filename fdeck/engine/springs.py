"""Contact springs integrated linearly implicitly (``contact[].springs: implicit``): the nodes' penalty and stick
springs no longer bound the stable step.

A contact node i of pair p in contact at t_n carries the spring stiffness K = k_n n n^T + k_t (I - n n^T) [N/mm]
(k_n = A dp/dh, the normal law's tangent times the node's area; k_t its stick spring while it sticks, 0 while it
slides or without friction; ``effects.contact.contact_forces`` fills both). Central differences take the contact
force at x_n for the whole step, and a spring stiffer than m / dt^2 then rings and grows. Here the force over the
step is the spring's force at x_(n+1) linearised about x_n:

    f_c(x_n) + fc,   fc = -dt K (v(n+1/2) - v_tool)    (v_tool: the tool's velocity over the step)

so the node's update solves (m + dt dt_avg K) a = r - dt K (v(n-1/2) - v_tool) instead of m a = r (r the forces
at t_n). For a spring alone, x'' = -w^2 x, the step then maps (x, dt v) through 1/(1 + h) [[1, 1], [-h, 1]],
h = dt^2 w^2, whose determinant is 1 / (1 + h) < 1: stable for any step, and dissipative (a backward-Euler-like
treatment of the spring alone; the elements stay explicit, and a node's element stiffness now acts on m + dt dt_avg
K, so their bound is not lowered either). At rest (v = v_tool) fc = 0: the quasi-static answer is the explicit
one's. Used for the springs of a node while it is in contact; a node closing on a tool is caught explicitly the
cycle it first comes within the law's reach, which is why the exponential law (its stiffness rising from zero) is
required, and a sliding node's return to sticking is decided on its stick spring explicitly at the next call, which
jitters between slip directions once dt^2 k_t / m passes about 4: the pair keeps the step below 2 sqrt(m / k_t)
(``effects.contact.RigidContact.implicit_bound``).

The energy: fc is a viscous force on the node's velocity relative to the tool. The engine books it with the forces
at t_n (``f_int``), so the blank receives its trapezoidal work sum 1/2 (fc_(n-1) + fc_n) . dx; the pair books the
tool's share 1/2 (Fc_(n-1) + Fc_n) . du (du its translation increment, Fc = sum fc) as tool work and the difference
as ``contact_implicit_dissipation``, so the balance closes. Its size is the price of the larger step: a node
oscillating on its spring loses energy each cycle where the explicit spring would have rung.

With lumped mass each node solves its 3 x 3 system in closed form (the springs of several pairs at one node
summed); with selective mass scaling the spring terms join the conjugate-gradient operator (``selective_mass``:
M + dM + dt dt_avg K) and its diagonal preconditioner. Prescribed dofs (symmetry planes) are known in both: the
constraints act first, and the solves take their velocity changes to the right-hand side (their reactions then
carry the springs' share there).

Shapes: entries e (the nodes in contact, a node once per pair): node (e,) int64, K (e, 6) [N/mm] as (xx, xy, xz,
yy, yz, zz), vt (e, 3) [mm/s]; nodal arrays (n_node, 3).
"""

from __future__ import annotations

import numpy as np

from fdeck.engine.effect import free_dofs
from fdeck.jit import njit


@njit
def fill_entries(slots, nodes, nrm, stiff, vt, out_node, out_K, out_vt, o):
    """Entries o.. of the pair's contact slots ``slots`` (j,): node, K from its normal nrm (k, 3) and stiffnesses
    stiff (k, 2) [N/mm], the tool velocity vt (3,)."""
    for j in range(slots.shape[0]):
        i = slots[j]
        n0, n1, n2 = nrm[i, 0], nrm[i, 1], nrm[i, 2]
        kn, kt = stiff[i, 0], stiff[i, 1]
        d = kn - kt
        e = o + j
        out_node[e] = nodes[i]
        out_K[e, 0], out_K[e, 1], out_K[e, 2] = kt + d * n0 * n0, d * n0 * n1, d * n0 * n2
        out_K[e, 3], out_K[e, 4], out_K[e, 5] = kt + d * n1 * n1, d * n1 * n2, kt + d * n2 * n2
        out_vt[e, 0], out_vt[e, 1], out_vt[e, 2] = vt[0], vt[1], vt[2]


@njit
def _times(K, e, p0, p1, p2):
    """K_e p as three scalars."""
    return (K[e, 0] * p0 + K[e, 1] * p1 + K[e, 2] * p2, K[e, 1] * p0 + K[e, 3] * p1 + K[e, 4] * p2,
            K[e, 2] * p0 + K[e, 4] * p1 + K[e, 5] * p2)


@njit
def add_product(node, K, c, p, q):
    """q += c K p at the entries' nodes (serial: a node may appear once per pair)."""
    for e in range(node.shape[0]):
        i = node[e]
        y0, y1, y2 = _times(K, e, p[i, 0], p[i, 1], p[i, 2])
        q[i, 0] += c * y0
        q[i, 1] += c * y1
        q[i, 2] += c * y2


@njit
def add_rhs(node, K, vt, dt, v_old, r):
    """r -= dt K (v_old - vt) at the entries' nodes [N]."""
    for e in range(node.shape[0]):
        i = node[e]
        y0, y1, y2 = _times(K, e, v_old[i, 0] - vt[e, 0], v_old[i, 1] - vt[e, 1], v_old[i, 2] - vt[e, 2])
        r[i, 0] -= dt * y0
        r[i, 1] -= dt * y1
        r[i, 2] -= dt * y2


@njit
def precondition(node, K, c, diag, free, dinv, add, seen):
    """dinv = free / (diag + c diag(K)) at the entries' nodes, the K of every pair at a node summed (``add``), or
    back to free / diag; seen (n_node,) scratch, left False (a node of several pairs is inverted once)."""
    for e in range(node.shape[0]):
        i = node[e]
        for j in range(3):
            dinv[i, j] = diag[i, j]
    if add:
        for e in range(node.shape[0]):
            i = node[e]
            dinv[i, 0] += c * K[e, 0]
            dinv[i, 1] += c * K[e, 3]
            dinv[i, 2] += c * K[e, 5]
    for e in range(node.shape[0]):
        i = node[e]
        if seen[i]:
            continue
        seen[i] = True
        for j in range(3):
            dinv[i, j] = free[i, j] / dinv[i, j] if dinv[i, j] > 0.0 else 0.0
    for e in range(node.shape[0]):
        seen[node[e]] = False


@njit
def lumped_solve(node, K, vt, m, v, v_old, free, c, Ks, bs, seen):
    """After the lumped kick (v = v_old + dt_avg r / m) and the constraints (v prescribed where free is 0): v of each
    entry's node on its free dofs from (m + c K) (v - v_old) = m (v - v_old)_kick - c K (v_old - vt), the K of its
    pairs summed (c = dt dt_avg), the prescribed dofs' v - v_old known (moved to the right-hand side). Ks (n_node,
    6), bs (n_node, 3), seen (n_node,) scratch, left zeroed."""
    for e in range(node.shape[0]):
        i = node[e]
        for j in range(6):
            Ks[i, j] += K[e, j]
        y0, y1, y2 = _times(K, e, v_old[i, 0] - vt[e, 0], v_old[i, 1] - vt[e, 1], v_old[i, 2] - vt[e, 2])
        bs[i, 0] += y0
        bs[i, 1] += y1
        bs[i, 2] += y2
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for e in range(node.shape[0]):
        i = node[e]
        if seen[i]:
            continue
        seen[i] = True
        A[0, 0], A[0, 1], A[0, 2] = m[i] + c * Ks[i, 0], c * Ks[i, 1], c * Ks[i, 2]
        A[1, 1], A[1, 2], A[2, 2] = m[i] + c * Ks[i, 3], c * Ks[i, 4], m[i] + c * Ks[i, 5]
        A[1, 0], A[2, 0], A[2, 1] = A[0, 1], A[0, 2], A[1, 2]
        for j in range(3):
            b[j] = m[i] * (v[i, j] - v_old[i, j]) - c * bs[i, j]
        for j in range(3):  # a prescribed dof: its known change to the other rows' right-hand side, its row e_j
            if free[i, j] == 0.0:
                dv = v[i, j] - v_old[i, j]
                for k in range(3):
                    if k != j:
                        b[k] -= A[k, j] * dv
                        A[k, j] = 0.0
                        A[j, k] = 0.0
                A[j, j] = 1.0
                b[j] = dv
        # symmetric 3 x 3 by its adjugate (positive definite: m > 0, K positive semi-definite)
        c00, c01, c02 = A[1, 1] * A[2, 2] - A[1, 2] * A[1, 2], A[0, 2] * A[1, 2] - A[0, 1] * A[2, 2], \
            A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]
        c11, c12, c22 = A[0, 0] * A[2, 2] - A[0, 2] * A[0, 2], A[0, 1] * A[0, 2] - A[0, 0] * A[1, 2], \
            A[0, 0] * A[1, 1] - A[0, 1] * A[0, 1]
        det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
        v[i, 0] = v_old[i, 0] + (c00 * b[0] + c01 * b[1] + c02 * b[2]) / det
        v[i, 1] = v_old[i, 1] + (c01 * b[0] + c11 * b[1] + c12 * b[2]) / det
        v[i, 2] = v_old[i, 2] + (c02 * b[0] + c12 * b[1] + c22 * b[2]) / det
    for e in range(node.shape[0]):
        i = node[e]
        seen[i] = False
        for j in range(6):
            Ks[i, j] = 0.0
        bs[i, 0] = bs[i, 1] = bs[i, 2] = 0.0


@njit
def spring_forces(node, K, vt, slots, dt, v, fc, f_int, o):
    """fc (k, 3) of one pair [N] = -dt K (v - vt) at its entries o.. (slots (j,) its slot of each), subtracted from
    f_int (the engine's resisting sign); other slots left as they are (zeroed by the caller). Returns the sum."""
    s0 = s1 = s2 = 0.0
    for j in range(slots.shape[0]):
        e = o + j
        i = node[e]
        y0, y1, y2 = _times(K, e, v[i, 0] - vt[e, 0], v[i, 1] - vt[e, 1], v[i, 2] - vt[e, 2])
        k = slots[j]
        fc[k, 0], fc[k, 1], fc[k, 2] = -dt * y0, -dt * y1, -dt * y2
        f_int[i, 0] += dt * y0
        f_int[i, 1] += dt * y1
        f_int[i, 2] += dt * y2
        s0 += fc[k, 0]
        s1 += fc[k, 1]
        s2 += fc[k, 2]
    return s0, s1, s2


@njit
def blank_work(nodes, fc_prev, fc, dx):
    """sum over a pair's slots of 1/2 (fc_prev + fc) . dx[node] [mJ] (the trapezoidal work the engine's ledger sees
    on the blank), then fc_prev = fc and fc = 0."""
    w = 0.0
    for k in range(nodes.shape[0]):
        i = nodes[k]
        for j in range(3):
            w += 0.5 * (fc_prev[k, j] + fc[k, j]) * dx[i, j]
            fc_prev[k, j] = fc[k, j]
            fc[k, j] = 0.0
    return w


class Springs:
    """The run's implicit contact springs: the pairs (``effects.contact.RigidContact`` with ``implicit``) and the
    entries of the current cycle."""

    def __init__(self, pairs: list, n_node: int):
        self.pairs = pairs
        size = sum(len(p.nodes) for p in pairs)
        self.node, self.K, self.vt = np.zeros(size, np.int64), np.zeros((size, 6)), np.zeros((size, 3))
        self.count = 0
        self.slots: list[np.ndarray] = []
        self.Ks, self.bs, self.seen = np.zeros((n_node, 6)), np.zeros((n_node, 3)), np.zeros(n_node, bool)
        self.free = np.ones((n_node, 3))

    def prepare(self, constraints: list, x) -> None:
        """At a step's start: which translational dofs the constraints prescribe (``effect.free_dofs``)."""
        self.free = free_dofs(constraints, x)

    def gather(self, t: float, dt: float) -> None:
        """The entries of the nodes in contact at t_n (after the forces there), with each tool's velocity over
        [t, t + dt]."""
        o = 0
        self.slots = []
        for p in self.pairs:
            s = np.flatnonzero(p.stiff[:, 0] > 0.0)
            fill_entries(s, p.nodes, p.nrm, p.stiff, p.tool.velocity(t, dt), self.node, self.K, self.vt, o)
            self.slots.append(s)
            o += len(s)
        self.count = o

    def entries(self):
        """(node, K, vt) of the current entries (views)."""
        c = self.count
        return self.node[:c], self.K[:c], self.vt[:c]

    def lumped(self, v, v_old, m, dt: float, dt_avg: float) -> None:
        """The lumped-mass update of the nodes in contact (after ``engine.integrate.kick`` and the constraints)."""
        node, K, vt = self.entries()
        lumped_solve(node, K, vt, m, v, v_old, self.free, dt * dt_avg, self.Ks, self.bs, self.seen)

    def finish(self, v, dt: float, f_int, dx) -> None:
        """With v(n+1/2) known: each pair's spring forces fc into f_int and its booking over the last increment dx
        (the engine's, x_n - x_(n-1))."""
        node, K, vt = self.entries()
        o = 0
        for p, s in zip(self.pairs, self.slots):
            total = spring_forces(node, K, vt, s, dt, v, p.fc, f_int, o)
            p.book_implicit(np.array(total), blank_work(p.nodes, p.fc_prev, p.fc, dx))
            o += len(s)
